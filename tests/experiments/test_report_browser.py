"""The reproduce report opened in a real browser: headless Chromium driven by Playwright.

Checks what a reader sees: every image loads, nothing is logged as an error, nothing is
fetched from outside the report folder, every section and its tables are there, and the
page fits a 1280 px window without horizontal overflow. Skips when Playwright or a
Chromium binary is missing (``.ci/run`` installs Debian's ``chromium``).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

pytest.importorskip("playwright.sync_api")

CHROMIUM = os.environ.get("QDCNN_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
if not Path(CHROMIUM).is_file():
    pytest.skip(f"no Chromium at {CHROMIUM}", allow_module_level=True)

from test_report import tiny_report  # noqa: E402  (the shared tiny run)

from qdcnn.experiments.reproduce import PAGE_ORDER  # noqa: E402

pytestmark = pytest.mark.slow

#: What the page shows, collected in the browser after load.
COLLECT = """() => ({
  images: Array.from(document.images).map(i => ({src: i.getAttribute('src'),
                                                  complete: i.complete, width: i.naturalWidth})),
  sections: Array.from(document.querySelectorAll('section')).map(s => ({
    id: s.id, title: s.querySelector('h2').textContent,
    tables: s.querySelectorAll('table').length, images: s.querySelectorAll('img').length,
    pre: s.querySelectorAll('pre').length, errors: s.querySelectorAll('p.error').length})),
  scrollWidth: document.documentElement.scrollWidth,
  clientWidth: document.documentElement.clientWidth,
  wide: Array.from(document.body.querySelectorAll('*'))
    .filter(e => e.getBoundingClientRect().right > document.documentElement.clientWidth + 0.5
                 && !e.closest('.scroll, pre'))
    .map(e => e.tagName + '.' + e.className).slice(0, 5),
})"""


@pytest.fixture(scope="module")
def seen(tmp_path_factory: pytest.TempPathFactory) -> dict:
    from playwright.sync_api import sync_playwright

    out, _ = tiny_report(tmp_path_factory)
    folder = out / "report"
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            console: list[str] = []
            requests: list[str] = []
            page.on("console", lambda m: console.append(f"{m.type}: {m.text}"))
            page.on("pageerror", lambda e: console.append(f"pageerror: {e}"))
            page.on("requestfailed", lambda r: console.append(f"requestfailed: {r.url}"))
            page.on("request", lambda r: requests.append(r.url))
            page.goto((folder / "index.html").as_uri())
            page.wait_for_load_state("load")
            info = page.evaluate(COLLECT)
        finally:
            browser.close()
    return info | {"console": console, "requests": requests, "folder": folder}


def test_every_image_loads(seen: dict) -> None:
    assert seen["images"], "the report shows no figure"
    broken = [i["src"] for i in seen["images"] if not (i["complete"] and i["width"] > 0)]
    assert broken == []


def test_no_console_errors_and_nothing_fetched_from_outside(seen: dict) -> None:
    assert [m for m in seen["console"] if not m.startswith(("log:", "info:"))] == []
    root = seen["folder"].resolve().as_uri()
    assert all(url.startswith(root) for url in seen["requests"]), seen["requests"]


def test_every_section_and_its_tables_are_on_the_page(seen: dict) -> None:
    sections = {s["id"]: s for s in seen["sections"]}
    assert list(sections) == list(PAGE_ORDER)
    for sid in PAGE_ORDER:
        stored = json.loads((seen["folder"] / "sections" / f"{sid}.json").read_text())
        kinds = [b["kind"] for b in stored["blocks"]]
        shown = sections[sid]
        assert shown["title"].startswith(stored["title"].split(":")[0]), shown["title"]
        assert shown["tables"] == kinds.count("table"), sid
        assert shown["images"] == kinds.count("figure"), sid
        assert shown["pre"] == kinds.count("pre"), sid
        assert shown["errors"] == kinds.count("error"), sid
    assert sections["table-i"]["tables"] >= 2 and sections["fig-7"]["images"] >= 3


def test_the_page_fits_1280_px_without_horizontal_overflow(seen: dict) -> None:
    assert seen["clientWidth"] == 1280
    assert seen["scrollWidth"] <= seen["clientWidth"], seen["wide"]
    assert seen["wide"] == []
