"""The README's example runs as written and says what the README claims."""

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def _python_blocks():
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)


def test_readme_example_runs(capsys):
    blocks = _python_blocks()
    assert blocks, "the README has no python example"
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)  # noqa: S102 - our own README
    run, cmd = namespace["run"], namespace["cmd"]
    assert run.completed
    assert float(run.position_error.max()) < 1e-3  # the governor keeps the tool on the line
    assert cmd.qd.shape == (6,)
    out = capsys.readouterr().out
    assert "regular" in out  # analyze(...) printed its report
    # the status the README's comment shows is the one the example prints
    said = re.search(r"print\(cmd\.status, cmd\.qd\)\s+# (\S+)", blocks[0])
    assert said and cmd.status == said.group(1), (cmd.status, said)


def test_readme_example_is_short():
    assert len(_python_blocks()[0].strip().splitlines()) <= 20


ROOT = README.parent


def test_readme_says_how_to_install_from_the_source_tree():
    text = README.read_text(encoding="utf-8")
    assert "not on a package index" in text and 'pip install -e ".[plot]"' in text
    assert "a few seconds" not in text                      # measured: about 3 s
    said = re.search(r"print\(cmd\.status, cmd\.qd\)\s+# (\S+)", text).group(1)
    assert f"prints `{said}`" in text.split("```python")[1].split("```")[1]   # explained after the example


def test_no_mention_of_files_outside_the_repository():
    pattern = re.compile(r"DESIGN\.md|DESIGN/|/work/|shared/DESIGN")
    offenders = []
    for folder, suffixes in (("docs", (".md",)), ("ratectl", (".py",)), ("examples", (".py",)),
                             ("tests", (".py",)), ("benchmarks", (".py",))):
        for p in (ROOT / folder).rglob("*"):
            if p.suffix in suffixes and p.resolve() != Path(__file__).resolve():
                for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
                    if pattern.search(line):
                        offenders.append(f"{p.relative_to(ROOT)}:{i}: {line.strip()}")
    offenders += [f"README.md: {line}" for line in README.read_text(encoding="utf-8").splitlines()
                  if pattern.search(line)]
    assert not offenders, "\n".join(offenders)


def test_docstrings_use_no_sphinx_roles():
    """The API pages are rendered by mkdocstrings (Markdown): RST roles would show raw."""
    role = re.compile(r":(?:py:)?(?:class|meth|func|mod|data|attr|exc|obj):`")
    offenders = [f"{p.relative_to(ROOT)}:{i}" for p in (ROOT / "ratectl").rglob("*.py")
                 for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if role.search(line)]
    assert not offenders, offenders


def test_docs_formulas_are_typeset_not_code():
    """Theory pages write formulas as TeX ($...$), not Unicode inside code blocks."""
    for page in sorted((ROOT / "docs" / "theory").glob("*.md")):
        text = page.read_text(encoding="utf-8")
        assert "$$" in text, page.name
        indented = [line for line in text.splitlines()
                    if line.startswith("    ") and any(c in line for c in "q̇σλξ‖ᵀ⁻Σ×")]
        assert not indented, (page.name, indented[:3])
