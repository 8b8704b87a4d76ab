"""A small report document rendered both as Markdown and as one self-contained HTML page.

The benchmark builds a :class:`Report` of headings, paragraphs, tables and figures; the Markdown
refers to PNG files written next to it, the HTML embeds the same PNGs as base64 so that the page
can be mailed or opened anywhere without its folder.

Examples
--------
>>> rep = Report("Demo")
>>> rep.heading("Numbers")
>>> rep.table(["method", "A"], [["parametric", 0.0109]], caption="A values")
>>> "| parametric | 0.0109 |" in rep.to_markdown()
True
>>> "<td>parametric</td>" in rep.to_html()
True
"""

from __future__ import annotations

import base64
import dataclasses
import html
import math
import os
from collections.abc import Sequence
from typing import Any

__all__ = ["Report", "format_value"]


def format_value(v: Any, digits: int = 3) -> str:
    """A table cell: numbers to ``digits`` significant digits, NaN/None as an en dash."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            return "–" if math.isnan(v) else ("∞" if v > 0 else "−∞")
        return f"{v:.{digits}g}"
    return str(v)


@dataclasses.dataclass
class _Block:
    kind: str
    payload: dict


class Report:
    """An ordered list of blocks: headings, paragraphs, lists, tables, figures.

    Parameters
    ----------
    title : str
        The page title (first heading).

    Examples
    --------
    >>> from charcurves.report import Report
    >>> rep = Report("Duffing study")
    >>> rep.heading("Numbers")
    >>> rep.table(["method", "A"], [["parametric", 0.0109]], caption="A values")
    >>> print(rep.to_markdown().splitlines()[0])
    # Duffing study
    >>> "<td>parametric</td>" in rep.to_html()
    True
    """

    def __init__(self, title: str):
        self.title = str(title)
        self.blocks: list[_Block] = []
        self._figure_names: set[str] = set()

    # ------------------------------------------------------------------ building
    def heading(self, text: str, level: int = 2) -> None:
        """A section heading (level 2..4; level 1 is the title)."""
        self.blocks.append(_Block("heading", {"text": str(text), "level": int(min(max(level, 2), 4))}))

    def paragraph(self, text: str) -> None:
        """A paragraph of plain text (``code`` in backticks is kept as code)."""
        self.blocks.append(_Block("paragraph", {"text": str(text)}))

    def bullets(self, items: Sequence[str]) -> None:
        """A bulleted list of plain-text items."""
        self.blocks.append(_Block("bullets", {"items": [str(i) for i in items]}))

    def table(self, header: Sequence[str], rows: Sequence[Sequence[Any]], *, caption: str | None = None,
              digits: int = 3) -> None:
        """A table; numeric cells are formatted with :func:`format_value`."""
        head = [str(h) for h in header]
        body = [[c if isinstance(c, str) else format_value(c, digits) for c in r] for r in rows]
        for r in body:
            if len(r) != len(head):
                raise ValueError(f"a table row has {len(r)} cells, the header {len(head)}")
        self.blocks.append(_Block("table", {"header": head, "rows": body, "caption": caption}))

    def figure(self, fig_or_png, name: str, *, caption: str | None = None, dpi: int = 100) -> None:
        """A figure: a matplotlib Figure (saved as PNG and closed) or PNG bytes; ``name`` is its file stem."""
        if isinstance(fig_or_png, (bytes, bytearray)):
            png = bytes(fig_or_png)
        else:
            import io

            import matplotlib.pyplot as plt

            buf = io.BytesIO()
            fig_or_png.savefig(buf, format="png", dpi=dpi)
            plt.close(fig_or_png)
            png = buf.getvalue()
        stem = "".join(ch if ch.isalnum() or ch in "-_" else "-" for ch in str(name))
        base, k = stem, 2
        while stem in self._figure_names:
            stem, k = f"{base}-{k}", k + 1
        self._figure_names.add(stem)
        self.blocks.append(_Block("figure", {"png": png, "name": stem, "caption": caption}))

    # ------------------------------------------------------------------ Markdown
    def to_markdown(self, figure_dir: str = "figures") -> str:
        """Markdown text; figures are referred to as ``{figure_dir}/{name}.png``."""
        out = [f"# {self.title}", ""]
        for b in self.blocks:
            p = b.payload
            if b.kind == "heading":
                out += ["#" * p["level"] + " " + p["text"], ""]
            elif b.kind == "paragraph":
                out += [p["text"], ""]
            elif b.kind == "bullets":
                out += [f"- {i}" for i in p["items"]] + [""]
            elif b.kind == "table":
                if p["caption"]:
                    out += [f"*{p['caption']}*", ""]
                out.append("| " + " | ".join(_md_cell(h) for h in p["header"]) + " |")
                out.append("|" + "|".join("---" for _ in p["header"]) + "|")
                out += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in p["rows"]]
                out.append("")
            elif b.kind == "figure":
                out.append(f"![{p['caption'] or p['name']}]({figure_dir}/{p['name']}.png)")
                if p["caption"]:
                    out += ["", f"*{p['caption']}*"]
                out.append("")
        return "\n".join(out).rstrip() + "\n"

    # ------------------------------------------------------------------ HTML
    def to_html(self) -> str:
        """One self-contained HTML page (figures embedded as base64 PNG, inline CSS)."""
        parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
                 '<meta name="viewport" content="width=device-width, initial-scale=1">',
                 f"<title>{html.escape(self.title)}</title>", f"<style>{_CSS}</style></head><body><main>",
                 f"<h1>{html.escape(self.title)}</h1>"]
        toc = [b for b in self.blocks if b.kind == "heading" and b.payload["level"] == 2]
        if len(toc) > 2:
            parts.append('<nav><strong>Contents</strong><ol>')
            parts += [f'<li><a href="#s{i}">{html.escape(b.payload["text"])}</a></li>' for i, b in enumerate(toc)]
            parts.append("</ol></nav>")
        n2 = 0
        for b in self.blocks:
            p = b.payload
            if b.kind == "heading":
                anchor = ""
                if p["level"] == 2:
                    anchor, n2 = f' id="s{n2}"', n2 + 1
                parts.append(f"<h{p['level']}{anchor}>{html.escape(p['text'])}</h{p['level']}>")
            elif b.kind == "paragraph":
                parts.append(f"<p>{_inline(p['text'])}</p>")
            elif b.kind == "bullets":
                parts.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in p["items"]) + "</ul>")
            elif b.kind == "table":
                # the caption as a paragraph: a <caption> would wrap to the width of a narrow table
                cap = f'<p class="cap">{_inline(p["caption"])}</p>' if p["caption"] else ""
                head = "".join(f"<th>{html.escape(h)}</th>" for h in p["header"])
                body = "".join("<tr>" + "".join(_td(c) for c in r) + "</tr>" for r in p["rows"])
                parts.append(f'{cap}<div class="tw"><table><thead><tr>{head}</tr></thead>'
                             f"<tbody>{body}</tbody></table></div>")
            elif b.kind == "figure":
                data = base64.b64encode(p["png"]).decode("ascii")
                alt = html.escape(p["caption"] or p["name"], quote=True)
                cap = f"<figcaption>{_inline(p['caption'])}</figcaption>" if p["caption"] else ""
                parts.append(f'<figure><img alt="{alt}" src="data:image/png;base64,{data}">{cap}</figure>')
        parts.append("</main></body></html>")
        return "\n".join(parts) + "\n"

    # ------------------------------------------------------------------ files
    def write(self, out_dir: str | os.PathLike, stem: str = "report") -> tuple[str, str]:
        """Write ``{stem}.md`` (+ ``figures/*.png``) and ``{stem}.html`` atomically; returns both paths."""
        from ..io import atomic_write_bytes

        out_dir = os.fspath(out_dir)
        fig_dir = os.path.join(out_dir, "figures")
        os.makedirs(fig_dir, exist_ok=True)
        for b in self.blocks:
            if b.kind == "figure":
                atomic_write_bytes(os.path.join(fig_dir, b.payload["name"] + ".png"), b.payload["png"])
        md = os.path.join(out_dir, f"{stem}.md")
        page = os.path.join(out_dir, f"{stem}.html")
        atomic_write_bytes(md, self.to_markdown("figures").encode("utf-8"))
        atomic_write_bytes(page, self.to_html().encode("utf-8"))
        return md, page


def _td(text: str) -> str:
    """A cell; numbers are right-aligned, text left-aligned."""
    try:
        float(text.replace("−", "-").replace("∞", "inf"))
        numeric = True
    except ValueError:
        numeric = text == "–"
    return f'<td class="n">{html.escape(text)}</td>' if numeric else f"<td>{html.escape(text)}</td>"


def _md_cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _inline(text: str) -> str:
    """Escape text for HTML, turning `code` spans into <code>."""
    pieces = str(text).split("`")
    out = []
    for i, piece in enumerate(pieces):
        esc = html.escape(piece)
        out.append(f"<code>{esc}</code>" if i % 2 == 1 and i < len(pieces) - 1 else esc)
    return "".join(out)


_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;background:#fafafa;color:#222}
main{max-width:1320px;margin:0 auto;padding:1.5em 2em;background:#fff}
h1{border-bottom:2px solid #446;padding-bottom:.3em}
h2{margin-top:2em;border-bottom:1px solid #ccd;padding-bottom:.2em}
p,li{line-height:1.45}
code{background:#f0f0f4;padding:0 .25em;border-radius:3px}
nav ol{columns:2;font-size:.95em}
.tw{overflow-x:auto;margin:1em 0}
table{border-collapse:collapse;font-size:.9em}
.cap{font-style:italic;font-size:.92em;color:#333;margin:.8em 0 .2em}
th,td{border:1px solid #ccd;padding:.25em .6em;text-align:left;white-space:nowrap}
td.n{text-align:right}
th{background:#eef}
tbody tr:nth-child(even){background:#f7f7fb}
figure{margin:1.2em 0}
figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.9em;color:#444;margin-top:.3em}
"""
