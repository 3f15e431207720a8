"""A minimal single-page HTML report: a title, notes, a table of rows, linked images.

Cells that are paths to images (``.png``, ``.jpg``, ``.svg``) are shown as thumbnails linking
to the full image; floats are written with 4 significant digits; everything else is escaped
text. Links are relative to the report's directory when possible, so the folder can be moved.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence, Union

PathLike = Union[str, os.PathLike]
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".svg", ".gif")

_STYLE = """
body { font-family: sans-serif; margin: 1.5em; }
table { border-collapse: collapse; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.5em; text-align: right; vertical-align: middle; }
th { background: #eee; }
td.text { text-align: left; }
td.fail { background: #fdd; }
img.thumb { max-width: 160px; max-height: 160px; image-rendering: pixelated; }
figure { display: inline-block; margin: 0.5em; }
"""


def _href(target: PathLike, base: Path) -> str:
    p = Path(target)
    try:
        rel = os.path.relpath(p.resolve(), base.resolve())
    except ValueError:  # different drives
        rel = str(p)
    return html.escape(Path(rel).as_posix(), quote=True)


def format_cell(value: Any, base: Path) -> tuple[str, str]:
    """HTML for one cell and its CSS class."""
    if isinstance(value, (str, os.PathLike)) and os.fspath(value).lower().endswith(IMAGE_SUFFIXES):
        h = _href(value, base)
        return f'<a href="{h}"><img class="thumb" src="{h}" alt="{h}"></a>', "img"
    if isinstance(value, bool):
        return ("pass" if value else "FAIL"), ("text" if value else "text fail")
    if isinstance(value, float):
        return f"{value:.4g}", ""
    if isinstance(value, int):
        return str(value), ""
    return html.escape(str(value)), "text"


def write_report(path: PathLike, title: str, rows: Sequence[Mapping[str, Any]],
                 columns: Optional[Sequence[str]] = None,
                 images: Sequence[tuple[str, PathLike]] = (), notes: str = "") -> Path:
    """Write ``path`` (HTML): ``title``, ``notes`` (plain text paragraphs), a table, a gallery.

    ``columns`` defaults to the keys of all rows in first-seen order; ``images`` are
    ``(caption, path)`` pairs shown below the table. Returns the path written.
    """
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    base = out.parent
    if columns is None:
        cols: list[str] = []
        for r in rows:
            cols += [k for k in r if k not in cols]
    else:
        cols = list(columns)
    parts = ["<!DOCTYPE html>", '<html><head><meta charset="utf-8">',
             f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>",
             f"<h1>{html.escape(title)}</h1>"]
    for para in [p for p in notes.split("\n\n") if p.strip()]:
        parts.append(f"<p>{html.escape(para.strip())}</p>")
    if rows:
        parts.append("<table><thead><tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in cols)
                     + "</tr></thead><tbody>")
        for r in rows:
            cells = []
            for c in cols:
                text, cls = format_cell(r.get(c, ""), base)
                cells.append(f'<td class="{cls}">{text}</td>' if cls else f"<td>{text}</td>")
            parts.append("<tr>" + "".join(cells) + "</tr>")
        parts.append("</tbody></table>")
    for caption, img in images:
        h = _href(img, base)
        parts.append(f'<figure><a href="{h}"><img src="{h}" alt="{html.escape(caption)}"></a>'
                     f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    parts.append("</body></html>\n")
    out.write_text("\n".join(parts), encoding="utf-8")
    return out
