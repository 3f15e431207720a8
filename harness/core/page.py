"""The one HTML page writer of the harness: ``make report``, ``make regress`` and ``make study``
all write their pages through :func:`write_page` with the one stylesheet :data:`STYLE`.

A page is a title, intro notes, an optional contents list and :class:`Section` s; a section
is a heading (with an optional status badge), notes, a table, figures and any further
fragments. Everything given as plain data is escaped:

* table cells: image paths (``.png``, ``.jpg``, ``.svg``, ``.gif``) become thumbnails
  linking to the full image, floats get 4 significant digits, ``True``/``False`` become
  ``pass``/``FAIL``, everything else is text; :class:`Cell` sets a cell's CSS class,
  :class:`Markup` (made by :func:`link`, :func:`code`, :func:`figure`, ...) is trusted HTML;
* notes: plain text, paragraphs split at blank lines.

Pages fit a 1366 px window without scrolling sideways: a table wider than the window scrolls
inside its own box, numbers never break inside a value (numeric cells, and words with a digit
in text, do not wrap), and plots (:func:`plot`) are shown at their natural size, the size their
text was made for (:mod:`harness.core.plotting`), in a box that scrolls when the window is
narrower than the plot. ``tests/test_pages_browser.py`` checks all this in Chromium.

Links are written relative to the page's folder when they can be, so the folder can be moved.
"""

from __future__ import annotations

import html
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence, Union

from harness.core.files import write_whole

PathLike = Union[str, os.PathLike]
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".svg", ".gif")

#: The stylesheet of every page.
STYLE = """
body { font-family: sans-serif; margin: 1.5em; max-width: 90em; }
table { border-collapse: collapse; margin-bottom: 1.2em; }
div.tablebox, div.plotbox { max-width: 100%; overflow-x: auto; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.5em; text-align: right; vertical-align: top; }
th { background: #eee; }
td.text { text-align: left; }
td.wide { text-align: left; max-width: 24em; overflow-wrap: anywhere; }
td.num, span.nw { white-space: nowrap; }
.pass { background: #dfd; } .fail { background: #fdd; } .bless { background: #def; }
span.badge { font-size: 70%; padding: 0.1em 0.4em; border-radius: 0.3em; vertical-align: middle; }
img.thumb { max-width: 200px; max-height: 200px; image-rendering: pixelated; }
img.plot { max-width: none; }
figure { display: inline-block; margin: 0.4em; vertical-align: top; max-width: 100%; }
figure img { max-width: 100%; }
figure img.plot { max-width: none; }
img.wide { max-width: 100%; }
div.gallery { display: flex; flex-wrap: wrap; gap: 0.4em 0.8em; align-items: flex-start; }
div.gallery figure { margin: 0; }
figcaption { font-size: 85%; }
h2 { margin-top: 1.6em; border-bottom: 1px solid #ccc; }
h3 { margin: 1.2em 0 0.3em; }
p.note { max-width: 60em; }
code { font-size: 85%; overflow-wrap: anywhere; }
pre { background: #f4f4f4; padding: 0.5em; white-space: pre-wrap; overflow-wrap: anywhere; }
small { color: #444; }
"""


class Markup(str):
    """Trusted HTML: written as it is (everything else is escaped)."""


def esc(value: Any) -> Markup:
    """Text made safe for HTML (Markup stays as it is)."""
    return value if isinstance(value, Markup) else Markup(html.escape(str(value)))


def text_html(value: Any) -> Markup:
    """Escaped text whose number-like words are kept on one line (``span.nw``): a word with a
    digit and a character a browser may break after ("2.757e-08", "0.25/1/4", "-3%"), up to 32
    characters; a browser would otherwise break "2.757e-08" after its minus sign."""
    out = []
    for part in re.split(r"(\s+)", str(value)):
        e = html.escape(part)
        if (part and len(part) <= 32 and any(c.isdigit() for c in part)
                and any(c in "-+/:%,()[]" for c in part)):
            e = '<span class="nw">' + e + '</span>'
        out.append(e)
    return Markup("".join(out))


def join(*parts: Any, sep: str = "") -> Markup:
    """Parts (text escaped, Markup kept) joined into one fragment."""
    return Markup(sep.join(esc(p) for p in parts))


def tag(name: str, *content: Any, **attrs: Any) -> Markup:
    """``<name attrs>content</name>``; ``class_`` sets ``class``; None attributes are left out."""
    a = "".join(f' {k.rstrip("_")}="{html.escape(str(v), quote=True)}"' for k, v in attrs.items() if v is not None)
    return Markup(f"<{name}{a}>{join(*content)}</{name}>")


def href(target: PathLike, base: Optional[Path]) -> str:
    """``target`` relative to ``base`` (a folder) when possible, as a URL path."""
    p = Path(target)
    if base is None:
        return p.as_posix()
    try:
        rel = os.path.relpath(p.resolve(), Path(base).resolve())
    except ValueError:  # different drives
        rel = str(p)
    return Path(rel).as_posix()


def link(text: Any, target: str) -> Markup:
    return tag("a", text, href=target)


def code(text: Any) -> Markup:
    return tag("code", text)


def bold(text: Any) -> Markup:
    return tag("b", text)


def small(text: Any) -> Markup:
    return tag("small", text)


def pre(text: Any) -> Markup:
    return tag("pre", text)


def bullets(items: Sequence[Any]) -> Markup:
    return tag("ul", *[tag("li", x) for x in items]) if items else Markup("")


def image(path: PathLike, base: Optional[Path], alt: str = "", cls: Optional[str] = "thumb",
          width: Optional[int] = None) -> Markup:
    """A thumbnail that links to the full image."""
    h = href(path, base)
    return link(Markup(f'<img src="{html.escape(h, quote=True)}" alt="{html.escape(alt or h, quote=True)}"'
                       + (f' class="{cls}"' if cls else "") + (f' width="{int(width)}"' if width else "") + ">"), h)


def figure(path: PathLike, base: Optional[Path], caption: str) -> Markup:
    """A captioned image; a figure of :mod:`harness.core.plotting` (a PNG with a ``min-text-px``
    record) is shown as :func:`plot`, at its natural size."""
    body = plot(path, base, caption) if is_plot(path) else image(path, base, caption, cls=None)
    return tag("figure", body, tag("figcaption", caption))


def is_plot(path: PathLike) -> bool:
    """Whether ``path`` is a PNG written by :func:`harness.core.plotting.save` (it records
    ``min-text-px``): a figure with text, to be shown at its natural size."""
    p = Path(path)
    if p.suffix.lower() != ".png":
        return False
    try:
        with open(p, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return False
    return b"tEXtmin-text-px\x00" in head or b"iTXtmin-text-px\x00" in head


def plot(path: PathLike, base: Optional[Path], alt: str = "") -> Markup:
    """A figure shown at its natural size (its text was sized for that), in a box that scrolls
    sideways when the window is narrower; it links to the file."""
    return tag("div", image(path, base, alt, cls="plot"), class_="plotbox")


@dataclass(frozen=True)
class Cell:
    """A table cell with an explicit CSS class (``pass``, ``fail``, ``text``, ``wide``, ...)."""

    value: Any
    cls: str = ""


def format_cell(value: Any, base: Optional[Path]) -> tuple[str, str]:
    """HTML for one cell and its CSS class."""
    if isinstance(value, Cell):
        text, cls = format_cell(value.value, base)
        return text, " ".join(c for c in (cls, value.cls) if c)
    if isinstance(value, Markup):
        return value, "text"
    if isinstance(value, (str, os.PathLike)) and os.fspath(value).lower().endswith(IMAGE_SUFFIXES):
        if is_plot(value):
            return plot(value, base, os.fspath(value)), "img"
        return image(value, base), "img"
    if isinstance(value, bool):
        return ("pass" if value else "FAIL"), ("text" if value else "text fail")
    if isinstance(value, float):
        return f"{value:.4g}", "num"
    if isinstance(value, int):
        return str(value), "num"
    if value is None:
        return "", ""
    return text_html(value), "text"


def columns_of(rows: Sequence[Mapping[str, Any]], columns: Optional[Sequence[str]] = None) -> list[str]:
    """``columns``, or the keys of all rows in first-seen order."""
    if columns is not None:
        return list(columns)
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    return cols


def table(rows: Sequence[Mapping[str, Any]], columns: Optional[Sequence[str]] = None,
          base: Optional[Path] = None) -> Markup:
    """A table of ``rows`` (dicts: column -> value), empty cells for missing keys."""
    if not rows:
        return Markup("")
    cols = columns_of(rows, columns)
    parts = ['<div class="tablebox"><table><thead><tr>' + "".join(f"<th>{esc(c)}</th>" for c in cols)
             + "</tr></thead><tbody>"]
    for r in rows:
        cells = []
        for c in cols:
            text, cls = format_cell(r.get(c, ""), base)
            cells.append(f'<td class="{cls}">{text}</td>' if cls else f"<td>{text}</td>")
        parts.append("<tr>" + "".join(cells) + "</tr>")
    parts.append("</tbody></table></div>")
    return Markup("\n".join(parts))


def notes_html(notes: str, cls: Optional[str] = "note") -> Markup:
    """Plain-text paragraphs (split at blank lines), escaped."""
    if isinstance(notes, Markup):
        return tag("p", notes, class_=cls)
    return Markup("\n".join(tag("p", p.strip(), class_=cls) for p in notes.split("\n\n") if p.strip()))


@dataclass
class Section:
    """One section of a page: a heading (and status badge), notes, a table, figures, then
    ``body`` (further fragments, in order)."""

    title: str
    rows: Sequence[Mapping[str, Any]] = ()
    columns: Optional[Sequence[str]] = None
    notes: str = ""
    images: Sequence[tuple[str, PathLike]] = ()
    anchor: str = ""
    status: Optional[Cell] = None
    body: Sequence[Markup] = field(default_factory=tuple)


def slug(text: str, limit: int = 60) -> str:
    """A lower-case ``[a-z0-9-]`` name for anchors and file names ('x' when nothing is left)."""
    return re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-")[:limit] or "x"


def render_page(title: str, body: Sequence[Markup]) -> str:
    """The whole document: doctype, the stylesheet, the title as heading, the body."""
    return "\n".join(["<!DOCTYPE html>", '<html><head><meta charset="utf-8">',
                      f"<title>{esc(title)}</title><style>{STYLE}</style></head><body>",
                      f"<h1>{esc(title)}</h1>", *body, "</body></html>\n"])


def write_page(path: PathLike, title: str, sections: Sequence[Section], notes: str = "", *,
               contents: Optional[bool] = None, intro: Sequence[Markup] = ()) -> Path:
    """Write ``path`` (HTML): ``title``, ``notes``, ``intro`` fragments, a contents list (by
    default when there is more than one section), then each section. Returns the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    base = out.parent
    body: list[Markup] = [notes_html(notes), *intro]
    anchors = [s.anchor or slug(s.title) for s in sections]
    if contents if contents is not None else len(sections) > 1:
        body.append(bullets([link(s.title, f"#{a}") for a, s in zip(anchors, sections)]))
    for a, s in zip(anchors, sections):
        badge = ""
        if s.status is not None:
            badge = " " + tag("span", s.status.value, class_=f"badge {s.status.cls}".strip())
        body.append(Markup(f'<h2 id="{esc(a)}">{esc(s.title)}{badge}</h2>'))
        body.append(notes_html(s.notes))
        body.append(table(s.rows, s.columns, base))
        body += [figure(img, base, cap) for cap, img in s.images]
        body += list(s.body)
    write_whole(out, render_page(title, [b for b in body if b]))
    return out


def write_report(path: PathLike, title: str, rows: Sequence[Mapping[str, Any]],
                 columns: Optional[Sequence[str]] = None,
                 images: Sequence[tuple[str, PathLike]] = (), notes: str = "") -> Path:
    """A one-table page: ``title``, ``notes``, a table of ``rows``, then ``images``
    (``(caption, path)`` pairs)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    base = out.parent
    body = [notes_html(notes, None), table(rows, columns, base), *[figure(i, base, c) for c, i in images]]
    write_whole(out, render_page(title, [b for b in body if b]))
    return out
