"""Minimal HTML report writer with PNG figures (matplotlib, Agg backend).

Used by ``compare``, ``diagnose``, ``design``, ``analyze-impact`` and ``demo``::

    rep = Report("out/compare", "Model vs measurement")
    rep.heading("Fit")
    rep.table(["output", "fit %"], [["e_x", "97.1"], ["e_y", "96.4"]])
    fig, ax = rep.figure("timeseries", "Measured and simulated", nrows=2)
    ax[0].plot(...)
    rep.write()          # index.html, atomically; figures saved as they are added
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from rigd.fileio import atomic_write_text  # noqa: E402


class Report:
    """An HTML page with headings, text, tables and PNG figures in directory ``out``."""

    def __init__(self, out: str | Path, title: str):
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.title = title
        self._parts: list[str] = []
        self._pending: list[tuple[Any, str, str]] = []
        self.figures: list[Path] = []

    def heading(self, text: str, level: int = 2) -> None:
        self._flush()
        self._parts.append(f"<h{level}>{html.escape(text)}</h{level}>")

    def text(self, text: str) -> None:
        self._flush()
        self._parts.append(f"<p>{html.escape(text)}</p>")

    def pre(self, text: str) -> None:
        self._flush()
        self._parts.append(f"<pre>{html.escape(text)}</pre>")

    def table(self, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
        self._flush()
        h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>"
                       for r in rows)
        self._parts.append(f"<table><tr>{h}</tr>{body}</table>")

    def image(self, src: str, caption: str = "", href: str | None = None) -> None:
        """Show an image file that already exists, ``src`` relative to the page (a figure of
        another report); with ``href`` the image links there (relative too)."""
        self._flush()
        img = f'<img src="{html.escape(src)}" alt="{html.escape(caption or src)}">'
        if href:
            img = f'<a href="{html.escape(href)}">{img}</a>'
        self._parts.append(f"<figure>{img}<figcaption>{html.escape(caption)}</figcaption>"
                           "</figure>")

    def links(self, items: Sequence[tuple[str, str]], lead: str = "") -> None:
        """A paragraph of links ``(href, text)``, hrefs relative to the page."""
        self._flush()
        a = ", ".join(f'<a href="{html.escape(h)}">{html.escape(t)}</a>' for h, t in items)
        self._parts.append(f"<p>{html.escape(lead)}{a}</p>")

    def figure(self, name: str, caption: str = "", **subplots_kw):
        """Create a figure saved as ``name.png`` when the next element is added or on write."""
        self._flush()
        subplots_kw.setdefault("figsize", (9, 3.2 * subplots_kw.get("nrows", 1)))
        fig, ax = plt.subplots(**subplots_kw)
        self._pending.append((fig, name, caption))
        return fig, ax

    def _flush(self) -> None:
        for fig, name, caption in self._pending:
            path = self.out / f"{name}.png"
            fig.tight_layout()
            fig.savefig(path, dpi=90)
            plt.close(fig)
            self.figures.append(path)
            self._parts.append(f'<figure><img src="{html.escape(path.name)}" '
                               f'alt="{html.escape(name)}">'
                               f"<figcaption>{html.escape(caption)}</figcaption></figure>")
        self._pending.clear()

    def write(self, name: str = "index.html") -> Path:
        """Write the page atomically and return its path."""
        self._flush()
        page = ("<!doctype html><html><head><meta charset='utf-8'>"
                f"<title>{html.escape(self.title)}</title><style>"
                "body{font-family:sans-serif;max-width:1000px;margin:auto}"
                "table{border-collapse:collapse}td,th{border:1px solid #999;padding:2px 6px}"
                "img{max-width:100%}</style></head><body>"
                f"<h1>{html.escape(self.title)}</h1>" + "\n".join(self._parts) + "</body></html>")
        path = self.out / name
        atomic_write_text(path, page)
        return path
