"""Check the built documentation in a headless Chromium at 1280 px.

For every page of the site (default ``site/``): the page is served on 127.0.0.1, loaded
in ``chromium --headless`` with a 1280×900 window, and a probe script reports after
MathJax has typeset it:

* math: every ``.arithmatex`` element holds a MathJax rendering (``mjx-container``),
  no rendering is an error (``mjx-merror``), every glyph has its CSS (a font was
  loaded, not an empty box), and no raw ``\\(``, ``\\[`` or ``$$`` is left in the text;
* clipping: no box of the page content that clips or scrolls horizontally (code
  blocks, tables, display formulas) holds content wider than itself (``scrollWidth >
  clientWidth``), so nothing is cut off or hidden behind a scroll bar, and the page
  itself is not wider than the window.

Also checks the HTML without a browser: no raw Sphinx roles (``:class:`` and the like)
and no mention of files outside the repository. Exit status 1 with one line per
problem; ``--screenshots DIR`` also saves a PNG of each page.

Usage: ``python .ci/check_site.py [SITE_DIR] [--screenshots DIR]``.
"""

from __future__ import annotations

import argparse
import functools
import html
import http.server
import json
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

WIDTH, HEIGHT = 1280, 900
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--hide-scrollbars")
PROBE = r"""
<script>
(function () {
  function report() {
    const out = {math: 0, rendered: 0, errors: [], blank: 0, raw: [], clipped: [], page: 0};
    document.querySelectorAll('.arithmatex').forEach(el => {
      out.math += 1;
      if (el.querySelector('mjx-container')) out.rendered += 1;
      el.querySelectorAll('mjx-merror').forEach(e => out.errors.push(e.textContent.slice(0, 80)));
    });
    document.querySelectorAll('mjx-c').forEach(c => {
      const content = getComputedStyle(c, '::before').content;
      if (!content || content === 'none') out.blank += 1;
    });
    const content = document.querySelector('.md-content') || document.body;
    const walker = document.createTreeWalker(content, NodeFilter.SHOW_TEXT);
    while (walker.nextNode()) {
      const t = walker.currentNode;
      if (t.parentElement.closest('code, pre, mjx-container, script, .arithmatex')) continue;
      const m = t.textContent.match(/\\\(|\\\[|\$\$/);
      if (m) out.raw.push(t.textContent.trim().slice(0, 80));
    }
    content.querySelectorAll('*').forEach(el => {
      // a box that clips or scrolls its content horizontally, and whose content is wider
      const st = getComputedStyle(el);
      if (st.overflowX === 'visible' || el.clientWidth === 0) return;
      if (el.closest('mjx-assistive-mml')) return;
      if (el.scrollWidth > el.clientWidth + 1) {
        const cls = typeof el.className === 'string' ? el.className.trim() : '';
        out.clipped.push({tag: el.tagName.toLowerCase() + (cls ? '.' + cls.split(/\s+/).join('.') : ''),
                          box: el.clientWidth, content: el.scrollWidth,
                          text: (el.textContent || '').trim().replace(/\s+/g, ' ').slice(0, 70)});
      }
    });
    out.page = document.documentElement.scrollWidth;
    window.parent.postMessage({probe: out, page: location.pathname}, '*');
  }
  window.addEventListener('load', () => {
    const done = () => setTimeout(report, 300);
    const mj = window.MathJax;
    if (mj && mj.startup && mj.startup.promise) mj.startup.promise.then(done, done);
    else done();
  });
})();
</script>
"""
DRIVER = """<!doctype html><html><body>
<iframe id="f" style="width: %(w)dpx; height: %(h)dpx; border: 0"></iframe>
<script>
const pages = %(pages)s;
const results = {};
let i = 0;
function next() {
  if (i >= pages.length) {
    document.body.setAttribute('data-results', JSON.stringify(results));
    return;
  }
  document.getElementById('f').src = pages[i];
}
window.addEventListener('message', ev => {
  results[pages[i]] = ev.data.probe;
  i += 1;
  next();
});
next();
</script></body></html>
"""
SPHINX_ROLE = re.compile(r":(?:py:)?(?:class|meth|func|mod|data|attr|exc|obj|ref|doc):(?:`|<code)")
OUTSIDE_FILES = re.compile(r"DESIGN\.md|/work/|shared/", re.IGNORECASE)


def find_browser() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def serve(root: Path) -> tuple[http.server.ThreadingHTTPServer, str]:
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args) -> None:
            pass

    handler = functools.partial(Quiet, directory=str(root))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}"


def probe_pages(browser: str, root: str, site: Path, probes: list[str]) -> dict:
    """Load every probe page in one headless Chromium (an iframe of 1280×900 px, one page
    after the other) and return {probe path: result}."""
    driver = site / "_check_driver.html"
    driver.write_text(DRIVER % {"w": WIDTH, "h": HEIGHT, "pages": json.dumps(["/" + p for p in probes])},
                      encoding="utf-8")
    try:
        res = subprocess.run([browser, *FLAGS,
                              f"--window-size={WIDTH + 40},{HEIGHT + 40}",
                              f"--virtual-time-budget={20000 * len(probes)}", "--dump-dom",
                              f"{root}/_check_driver.html"],
                             capture_output=True, text=True, timeout=60 + 15 * len(probes))
    finally:
        driver.unlink(missing_ok=True)
    m = re.search(r'data-results="([^"]*)"', res.stdout)
    if m is None:
        raise RuntimeError(f"chromium gave no result (exit {res.returncode}): {res.stderr.strip()[-300:]}")
    found = json.loads(html.unescape(m.group(1)))
    return {p: found.get("/" + p) for p in probes}


def screenshot(browser: str, url: str, shot: Path) -> None:
    subprocess.run([browser, *FLAGS,
                    f"--window-size={WIDTH},{HEIGHT}", "--virtual-time-budget=5000",
                    f"--screenshot={shot}", url], capture_output=True, timeout=120)


def static_checks(site: Path) -> list[str]:
    problems = []
    for page in sorted(site.rglob("*.html")):
        text = page.read_text(encoding="utf-8")
        body = re.sub(r"<script.*?</script>", "", text, flags=re.DOTALL)
        for m in SPHINX_ROLE.finditer(body):
            problems.append(f"{page.relative_to(site)}: raw Sphinx role {m.group(0)!r}: "
                            f"...{html.unescape(body[m.start():m.start() + 60])}...")
        for m in OUTSIDE_FILES.finditer(body):
            problems.append(f"{page.relative_to(site)}: mentions a file outside the repository: "
                            f"...{body[max(0, m.start() - 40):m.end() + 20]}...")
    return problems


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("site", nargs="?", default="site", type=Path)
    ap.add_argument("--screenshots", type=Path, help="save a PNG of every page here")
    ap.add_argument("--no-browser", action="store_true", help="only the HTML checks")
    args = ap.parse_args(argv)
    site: Path = args.site
    if not (site / "index.html").is_file():
        print(f"check_site: no built site at {site} (run mkdocs build first)", file=sys.stderr)
        return 2
    problems = static_checks(site)
    pages = sorted(p for p in site.rglob("index.html") if p.parent.name not in ("search", "assets"))
    n_math = 0
    if not args.no_browser:
        browser = find_browser()
        if browser is None:
            print("check_site: no chromium found (apt-get install chromium)", file=sys.stderr)
            return 2
        if args.screenshots:
            args.screenshots.mkdir(parents=True, exist_ok=True)
        jobs = []
        for page in pages:
            rel = page.parent.relative_to(site)
            probe = page.parent / "_probe.html"
            probe.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"),
                             encoding="utf-8")
            jobs.append((str(rel), probe))
        server, root = serve(site)
        try:
            found = probe_pages(browser, root, site, [j[1].relative_to(site).as_posix() for j in jobs])
            results = [found[j[1].relative_to(site).as_posix()] or {"failed": "the page did not report"}
                       for j in jobs]
            if args.screenshots:
                args.screenshots.mkdir(parents=True, exist_ok=True)
                for rel, _ in jobs:
                    name = "index" if rel == "." else rel.replace("/", "_")
                    url = f"{root}/" if rel == "." else f"{root}/{rel}/"
                    screenshot(browser, url, args.screenshots / f"{name}.png")
        finally:
            server.shutdown()
            for _, probe in jobs:
                probe.unlink(missing_ok=True)
        for (rel, _), r in zip(jobs, results, strict=True):
            where = rel if rel != "." else "index"
            if "failed" in r:
                problems.append(f"{where}: {r['failed']}")
                continue
            n_math += r["math"]
            if r["rendered"] != r["math"]:
                problems.append(f"{where}: {r['math'] - r['rendered']} of {r['math']} formulas not typeset")
            for e in r["errors"]:
                problems.append(f"{where}: MathJax error: {e}")
            if r["blank"]:
                problems.append(f"{where}: {r['blank']} math glyphs without a font (blank boxes)")
            for t in r["raw"]:
                problems.append(f"{where}: raw TeX delimiter left in the text: {t!r}")
            for c in r["clipped"]:
                problems.append(f"{where}: {c['tag']} is {c['content']} px wide in a {c['box']} px box: "
                                f"{c['text']!r}")
            if r["page"] > WIDTH:
                problems.append(f"{where}: the page is {r['page']} px wide at a {WIDTH} px window")
    for p in problems:
        print(p)
    print(f"check_site: {len(pages)} pages, {n_math} formulas, {len(problems)} problems", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
