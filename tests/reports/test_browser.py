"""report.html in real headless Chromium: it loads without errors and every <img> decodes (naturalWidth > 0).

Chromium (Debian package ``chromium``) is installed by a session fixture when missing and running as root;
otherwise the tests fail with instructions (they never skip).  The page is checked through ``--dump-dom``:
a small script, injected into a copy of the report next to it, records on ``<body>`` (as data attributes)
the number of images, the broken ones and any error event once the page has loaded.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest
from test_reports import make_results

from reports.build import write_report

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
  b.dataset.errors = JSON.stringify(window.__errors);
  b.dataset.checked = 'yes';
});
</script>"""


@pytest.fixture(scope="session")
def chromium() -> Path:
    """Path of the Chromium binary, installing the Debian package first if needed (root only)."""
    if not CHROMIUM.exists():
        if os.geteuid() != 0:
            pytest.fail(f"{CHROMIUM} is missing and these tests are not running as root: "
                        "install it with `sudo apt-get update && sudo apt-get install -y chromium`")
        for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "chromium"]):
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1200,
                                  env={**os.environ, "DEBIAN_FRONTEND": "noninteractive"})
            if proc.returncode != 0:
                pytest.fail(f"`{' '.join(cmd)}` failed ({proc.returncode}): {proc.stderr.strip()[-800:]}")
        if not CHROMIUM.exists():
            pytest.fail(f"apt-get installed chromium but {CHROMIUM} still does not exist")
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
    res = make_results(tmp_path)
    html_file = write_report(res, ply="paper", cloud_points=300)
    expected_imgs = html_file.read_text(encoding="utf-8").count("<img ")
    assert expected_imgs == 7  # 3 summary figures + (error maps, clouds) for 2 configurations
    attrs, dom_imgs, stderr = load_in_chromium(chromium, html_file, tmp_path)
    assert attrs.get("data-checked") == "yes", f"the load handler did not run; body attributes: {attrs}"
    assert int(attrs["data-img-count"]) == expected_imgs == dom_imgs
    assert json.loads(attrs["data-broken"]) == [], f"images not shown: {attrs['data-broken']}"
    assert json.loads(attrs["data-errors"]) == [], f"errors while loading: {attrs['data-errors']}"
    assert _console_lines(stderr) == []


def test_checker_detects_a_broken_image(chromium, tmp_path):
    # the same probe must fail on a page with an undecodable image, or the test above proves nothing
    page = tmp_path / "broken.html"
    page.write_text('<!DOCTYPE html><html><head><title>x</title></head><body>'
                    '<img alt="not a png" src="data:image/png;base64,AAAA"></body></html>', encoding="utf-8")
    attrs, _, _ = load_in_chromium(chromium, page, tmp_path)
    assert attrs.get("data-checked") == "yes"
    assert json.loads(attrs["data-broken"]) == ["not a png"]
    assert json.loads(attrs["data-errors"]) == ["failed to load: not a png"]
