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


def test_readme_example_is_short():
    assert len(_python_blocks()[0].strip().splitlines()) <= 20
