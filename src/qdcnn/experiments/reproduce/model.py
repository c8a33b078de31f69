"""A report section: its title (the paper's number), what it shows, and the numbers behind it.

A :class:`Section` holds rendering blocks (plain JSON dicts: text, table, figure,
preformatted text, note, error) and its numbers (``data``), so a finished section is
written to ``sections/<id>.json`` and a resumed run renders it again without recomputing.
Text is escaped when rendered; a pair of backticks marks code.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = ["STATUSES", "Cell", "Section", "cell"]

#: ``ok``: everything computed; ``partial``: some datasets or parts failed; ``failed``:
#: nothing could be computed; ``skipped``: left out on purpose; ``pending``: not computed
#: yet (a page written while the run goes on).
STATUSES: tuple[str, ...] = ("ok", "partial", "failed", "skipped", "pending")

Cell = str | dict[str, str]


def cell(text: object, cls: str = "") -> Cell:
    """A table cell with a CSS class (``paper``, ``measured``, ``estimate``, ``best``, ``na``)."""
    return {"text": str(text), "cls": cls} if cls else str(text)


@dataclass
class Section:
    """One section of the report.

    Attributes
    ----------
    id : str
        Anchor and file name (``table-i``, ``fig-7``).
    title : str
        Heading, beginning with the paper's number ("Table I: ...").
    status : str
        One of :data:`STATUSES`.
    blocks : list of dict
        What the page shows, in order.
    data : dict
        Every number of the section (report.json).
    notes : list of str
        What was left out or chosen, and why.
    errors : list of str
        One line per failure (a dataset that did not load, a part that raised).
    seconds : float
        Measured wall time of the section.
    """

    id: str
    title: str
    status: str = "ok"
    blocks: list[dict[str, Any]] = field(default_factory=list)
    data: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    seconds: float = 0.0

    # ------------------------------------------------------------ blocks

    def text(self, text: str) -> None:
        """A paragraph (escaped; `backticks` become code)."""
        self.blocks.append({"kind": "text", "text": text})

    def table(
        self,
        header: Sequence[str],
        rows: Sequence[Sequence[Cell]],
        *,
        caption: str = "",
        collapsed: bool = False,
    ) -> None:
        """A table; ``collapsed`` puts it inside a ``<details>`` element."""
        self.blocks.append(
            {
                "kind": "table",
                "header": list(header),
                "rows": [list(r) for r in rows],
                "caption": caption,
                "collapsed": collapsed,
            }
        )

    def figure(self, src: str, caption: str, alt: str = "") -> None:
        """An image file beside ``index.html`` (``src`` relative to it)."""
        self.blocks.append({"kind": "figure", "src": src, "caption": caption, "alt": alt})

    def pre(self, text: str, caption: str = "") -> None:
        """Preformatted text (circuit diagrams)."""
        self.blocks.append({"kind": "pre", "text": text, "caption": caption})

    def note(self, message: str) -> None:
        """Something left out or chosen on purpose; shown and listed in report.json."""
        self.notes.append(message)
        self.blocks.append({"kind": "note", "text": message})

    def error(self, message: str) -> None:
        """A failure inside this section; the section becomes ``partial``."""
        self.errors.append(message)
        self.blocks.append({"kind": "error", "text": message})
        if self.status == "ok":
            self.status = "partial"

    # ------------------------------------------------------------ files

    @property
    def figures(self) -> list[str]:
        """Image files the section shows."""
        return [b["src"] for b in self.blocks if b["kind"] == "figure"]

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "title": self.title,
            "status": self.status,
            "seconds": self.seconds,
            "notes": self.notes,
            "errors": self.errors,
            "figures": self.figures,
            "data": self.data,
            "blocks": self.blocks,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Section:
        """The section :meth:`to_dict` wrote."""
        return cls(
            d["id"],
            d["title"],
            d["status"],
            list(d["blocks"]),
            dict(d["data"]),
            list(d["notes"]),
            list(d["errors"]),
            float(d["seconds"]),
        )
