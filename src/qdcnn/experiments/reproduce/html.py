"""``index.html`` of a reproduce run: one self-contained page, no network, no script.

Figures are PNG files beside the page (``figures/``); the style sheet is inline. Tables
sit in scrolling containers and images are at most as wide as the page, so the page fits
a 1280 px window without horizontal overflow. Each section carries the paper's number
in its title and an ``id`` (``table-i``, ``fig-7``) to link to.
"""

from __future__ import annotations

import html
import re
from collections.abc import Sequence
from typing import Any

from qdcnn.experiments.reproduce.model import Section

__all__ = ["render_page"]

STYLE = """
*{box-sizing:border-box}
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;line-height:1.45;color:#1d1d1f;
 max-width:1180px;margin:0 auto;padding:0 16px 48px;overflow-wrap:anywhere}
h1{font-size:1.7em;margin:.8em 0 .3em}
h2{font-size:1.3em;margin:1.6em 0 .4em;padding-top:.6em;border-top:2px solid #d0d7de}
.status{font-size:.7em;font-weight:600;padding:2px 8px;border-radius:10px;vertical-align:middle;
 margin-left:8px;text-transform:uppercase}
.status-ok{background:#dafbe1;color:#116329}.status-partial{background:#fff8c5;color:#7d4e00}
.status-failed{background:#ffebe9;color:#a40e26}.status-skipped{background:#eaeef2;color:#57606a}
.scroll{overflow-x:auto;max-width:100%;margin:8px 0}
table{border-collapse:collapse;font-size:.88em}
caption{caption-side:top;text-align:left;font-weight:600;padding:4px 0}
th,td{border:1px solid #d0d7de;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#f6f8fa}
td.paper{background:#eef4ff}td.estimate{background:#fff3e0;font-style:italic}
td.best{font-weight:700;background:#e6f6e6}td.na{color:#6e7781}td.method{white-space:nowrap}
td.measured,td.best,td.paper{white-space:nowrap}
figure{margin:12px 0}img{max-width:100%;height:auto;display:block;border:1px solid #d0d7de}
figcaption{font-size:.88em;color:#57606a}
pre{overflow-x:auto;max-width:100%;background:#f6f8fa;padding:8px;font-size:.85em}
p.note{color:#57606a;border-left:3px solid #d0d7de;padding-left:8px}
p.error{color:#a40e26;border-left:3px solid #a40e26;padding-left:8px}
code{background:#f6f8fa;padding:0 3px}
nav ol{columns:2;font-size:.92em}
.legend span{display:inline-block;padding:0 6px;margin-right:6px}
"""

_CODE = re.compile(r"`([^`]+)`")
_EMPH = re.compile(r"\*([^*]+)\*")


def inline(text: str) -> str:
    """Escape ``text``; `code` and *emphasis* become elements.

    Examples
    --------
    >>> inline("use `--force` <now>")
    'use <code>--force</code> &lt;now&gt;'
    """
    escaped = html.escape(text, quote=False)
    return _EMPH.sub(r"<em>\1</em>", _CODE.sub(r"<code>\1</code>", escaped))


def _cell(value: Any, tag: str = "td") -> str:
    if isinstance(value, dict):
        cls = f' class="{html.escape(value.get("cls", ""))}"' if value.get("cls") else ""
        return f"<{tag}{cls}>{html.escape(value['text'])}</{tag}>"
    return f"<{tag}>{html.escape(str(value))}</{tag}>"


def _table(block: dict[str, Any]) -> str:
    caption = f"<caption>{inline(block['caption'])}</caption>" if block.get("caption") else ""
    head = "".join(_cell(h, "th") for h in block["header"])
    body = "".join("<tr>" + "".join(_cell(c) for c in row) + "</tr>" for row in block["rows"])
    table = (
        f'<div class="scroll"><table>{caption}<thead><tr>{head}</tr></thead>'
        f"<tbody>{body}</tbody></table></div>"
    )
    if block.get("collapsed"):
        summary = inline(block.get("caption") or "details")
        return f"<details><summary>{summary}</summary>{table}</details>"
    return table


def render_block(block: dict[str, Any]) -> str:
    """HTML of one section block."""
    kind = block["kind"]
    if kind == "text":
        return f"<p>{inline(block['text'])}</p>"
    if kind == "note":
        return f'<p class="note">Note: {inline(block["text"])}</p>'
    if kind == "error":
        return f'<p class="error">Error: {inline(block["text"])}</p>'
    if kind == "table":
        return _table(block)
    if kind == "pre":
        caption = f"<figcaption>{inline(block['caption'])}</figcaption>" if block["caption"] else ""
        return f"<figure>{caption}<pre>{html.escape(block['text'])}</pre></figure>"
    if kind == "figure":
        src = html.escape(block["src"])
        alt = html.escape(block.get("alt") or block["caption"])
        return (
            f'<figure><img src="{src}" alt="{alt}" loading="eager">'
            f"<figcaption>{inline(block['caption'])}</figcaption></figure>"
        )
    raise ValueError(f"unknown block kind {kind!r}")


def render_section(section: Section) -> str:
    """One ``<section>`` with its status badge, blocks and time."""
    badge = f'<span class="status status-{section.status}">{section.status}</span>'
    body = "".join(render_block(b) for b in section.blocks)
    if not section.blocks:
        body = '<p class="note">Not computed yet.</p>' if section.status == "pending" else ""
    timing = (
        f'<p class="note">Section computed in {section.seconds:.1f} s (measured).</p>'
        if section.seconds
        else ""
    )
    return (
        f'<section id="{html.escape(section.id)}"><h2>{inline(section.title)}{badge}</h2>'
        f"{body}{timing}</section>"
    )


def render_page(
    sections: Sequence[Section],
    *,
    title: str,
    intro: Sequence[str],
    settings: Sequence[tuple[str, str]],
    notes: Sequence[str],
    details: Sequence[tuple[str, str]] = (),
) -> str:
    """The whole page: title, introduction, settings, collapsed details, contents, sections."""
    toc = "".join(
        f'<li><a href="#{html.escape(s.id)}">{inline(s.title)}</a> ({html.escape(s.status)})</li>'
        for s in sections
    )
    rows = "".join(f"<tr><th>{html.escape(k)}</th><td>{inline(v)}</td></tr>" for k, v in settings)
    intro_html = "".join(f"<p>{inline(p)}</p>" for p in intro)
    notes_html = "".join(f'<p class="note">Note: {inline(n)}</p>' for n in notes)
    details_html = "".join(
        f"<details><summary>{inline(summary)}</summary><pre>{html.escape(text)}</pre></details>"
        for summary, text in details
    )
    legend = (
        '<p class="legend">Cells: <span style="background:#eef4ff">the paper\'s value</span>'
        '<span style="background:#e6f6e6;font-weight:700">best measured</span>'
        '<span style="background:#fff3e0;font-style:italic">estimate, not measured</span></p>'
    )
    return (
        '<!doctype html><html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>"
        f"<h1>{html.escape(title)}</h1>{intro_html}{legend}"
        f'<div class="scroll"><table id="settings"><tbody>{rows}</tbody></table></div>'
        f"{details_html}{notes_html}<nav><h2>Contents</h2><ol>{toc}</ol></nav>"
        + "".join(render_section(s) for s in sections)
        + "</body></html>"
    )
