"""report.html in real headless Chromium: it loads without errors and every <img> decodes (naturalWidth > 0).

Chromium (Debian package ``chromium``) is installed by ``make browser`` (which ``make test`` and ``.ci/run``
run first); when it is missing the tests fail with instructions (they never skip).  The page is checked
through ``--dump-dom``:
a small script, injected into a copy of the report next to it, records on ``<body>`` (as data attributes)
the number of images, the broken ones and any error event once the page has loaded; then it clicks headers of
the leaderboard (``table#leaderboard``) and records the row order after each click.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pandas as pd
import pytest

from harness.commands.report import build_report
from tests.reports.test_reports import CONFIGS, OTHERS, VARIANTS, make_results

pytestmark = pytest.mark.browser

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--enable-logging=stderr", "--v=0"]

CHECK_SCRIPT = """<script>
window.__errors = [];
window.addEventListener('error', function (e) {
  window.__errors.push(e.message || ('failed to load: ' + (e.target && (e.target.alt || e.target.tagName))));
}, true);
window.addEventListener('unhandledrejection', function (e) { window.__errors.push('rejection: ' + e.reason); });
window.addEventListener('load', function () {
  var imgs = Array.from(document.images);
  var broken = imgs.filter(function (i) { return !i.complete || i.naturalWidth === 0; })
                   .map(function (i) { return i.alt || i.src.slice(0, 60); });
  var b = document.body;
  b.dataset.imgCount = String(imgs.length);
  b.dataset.broken = JSON.stringify(broken);
  var table = document.getElementById('leaderboard');
  if (table) {
    var order = function () {
      return Array.prototype.map.call(table.tBodies[0].rows, function (r) { return r.cells[0].textContent; });
    };
    var click = function (key) {
      table.querySelector('th[data-key="' + key + '"]').dispatchEvent(new MouseEvent('click', {bubbles: true}));
      return order();
    };
    b.dataset.sorts = JSON.stringify({initial: order(), mae_first: click('mae_m'), mae_second: click('mae_m'),
                                      ause_first: click('ause')});
  }
  b.dataset.errors = JSON.stringify(window.__errors);
  b.dataset.checked = 'yes';
});
</script>"""


@pytest.fixture(scope="session")
def chromium() -> Path:
    """Path of the Chromium binary; installing it is `make browser`'s job (`.ci/run` calls it), never a test's."""
    if not CHROMIUM.exists():
        pytest.fail(f"{CHROMIUM} is missing: run `make browser` (as root: apt-get install chromium) before the "
                    "browser tests")
    return CHROMIUM


class _Body(HTMLParser):
    def __init__(self):
        super().__init__()
        self.attrs: dict | None = None
        self.img_count = 0

    def handle_starttag(self, tag, attrs):
        if tag == "body" and self.attrs is None:
            self.attrs = dict(attrs)
        if tag == "img":
            self.img_count += 1


def load_in_chromium(chromium: Path, html_file: Path, tmp_path: Path) -> tuple[dict, int, str]:
    """Open a copy of ``html_file`` (with the checking script) -> (body data attributes, <img> count, stderr)."""
    text = html_file.read_text(encoding="utf-8")
    assert "<head>" in text
    probe = html_file.with_name(html_file.stem + ".browser-check.html")  # beside it: relative links still work
    probe.write_text(text.replace("<head>", "<head>\n" + CHECK_SCRIPT, 1), encoding="utf-8")
    profile = tmp_path / "chromium-profile"
    try:
        proc = subprocess.run([str(chromium), *FLAGS, f"--user-data-dir={profile}", "--dump-dom",
                               probe.resolve().as_uri()], capture_output=True, text=True, timeout=180)
    finally:
        probe.unlink(missing_ok=True)
        shutil.rmtree(profile, ignore_errors=True)
    assert proc.returncode == 0, f"chromium exited {proc.returncode}: {proc.stderr[-2000:]}"
    parser = _Body()
    parser.feed(proc.stdout)
    assert parser.attrs is not None, f"no <body> in chromium's DOM dump: {proc.stdout[:500]!r}"
    return parser.attrs, parser.img_count, proc.stderr


def _console_lines(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ":CONSOLE" in ln]


def test_report_loads_and_every_image_is_shown(chromium, tmp_path):
    res = make_results(tmp_path, others=True)
    html_file = build_report(res, ply="paper", cloud_points=300).html_path
    expected_imgs = html_file.read_text(encoding="utf-8").count("<img ")
    # fig4, 2 breakdown plots, sparsification; per frame: error maps, region masks, clouds per configuration + others
    assert expected_imgs == 4 + 2 + len(CONFIGS) + 1
    attrs, dom_imgs, stderr = load_in_chromium(chromium, html_file, tmp_path)
    assert attrs.get("data-checked") == "yes", f"the load handler did not run; body attributes: {attrs}"
    assert int(attrs["data-img-count"]) == expected_imgs == dom_imgs
    assert json.loads(attrs["data-broken"]) == [], f"images not shown: {attrs['data-broken']}"
    assert json.loads(attrs["data-errors"]) == [], f"errors while loading: {attrs['data-errors']}"
    assert _console_lines(stderr) == []

    # the leaderboard: one row per method plus the paper's quoted rows, re-sorted by clicking headers
    board = pd.read_csv(res / "leaderboard.csv")
    sorts = json.loads(attrs["data-sorts"])
    n_methods = len(CONFIGS) * len(VARIANTS) + len(OTHERS)
    assert len(sorts["initial"]) == n_methods + 3 == len(board)
    assert sorts["initial"] == list(board["method"])  # tri360's rows by MAE, then the paper's
    assert (board["source"] == "paper").sum() == 3 and list(board["source"][-3:]) == ["paper"] * 3
    by_mae = list(board.sort_values("mae_m", kind="stable")["method"])  # every MAE differs: no ties
    assert board["mae_m"].nunique() == len(board)
    assert sorts["mae_first"] == by_mae  # first click on MAE: lower is better, ascending (paper rows mixed in)
    assert sorts["mae_first"] != sorts["initial"]  # a paper row beats some of ours: the order really changed
    assert sorts["mae_second"] == by_mae[::-1]  # second click reverses
    # AUSE: only `matcher` gave a confidence; rows without a value go last, keeping their previous order
    assert sorts["ause_first"] == ["matcher"] + [m for m in by_mae[::-1] if m != "matcher"]


def test_checker_detects_a_broken_image(chromium, tmp_path):
    # the same probe must fail on a page with an undecodable image, or the test above proves nothing
    page = tmp_path / "broken.html"
    page.write_text('<!DOCTYPE html><html><head><title>x</title></head><body>'
                    '<img alt="not a png" src="data:image/png;base64,AAAA"></body></html>', encoding="utf-8")
    attrs, _, _ = load_in_chromium(chromium, page, tmp_path)
    assert attrs.get("data-checked") == "yes"
    assert json.loads(attrs["data-broken"]) == ["not a png"]
    assert json.loads(attrs["data-errors"]) == ["failed to load: not a png"]
