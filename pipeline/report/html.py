"""The HTML page writer every report uses: one head and stylesheet, tables, figures, links.

Pages are self-contained apart from their images and links, which are relative paths, so a
stage or run folder can be moved or served as it is. Every text is escaped here; helpers
return HTML fragments (``str``) to be put together with :func:`page`.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from urllib.parse import quote

from ..io.artifacts import atomic_write_text

__all__ = ["STYLE", "esc", "fmt", "figure", "figures", "href", "kv_table", "link", "page",
           "table", "write_page"]

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222;
       line-height: 1.45; padding: 0 1em; }
table { border-collapse: collapse; font-size: 0.9em; margin: 1em 0; }
th, td { border: 1px solid #ccc; padding: 0.3em 0.6em; text-align: left; }
th { background: #f3f3f3; } tbody th { font-weight: normal; }
figure { margin: 1.5em 0; } img { max-width: 100%; border: 1px solid #ddd; }
figcaption, .caption { color: #555; font-size: 0.9em; }
code { background: #f4f4f4; padding: 0 0.2em; }
p.warn { background: #fcf3d9; border-left: 4px solid #e0a800; padding: 0.5em 0.8em; }
p.foot { color: #777; font-size: 0.8em; }
"""


def esc(x) -> str:
    return html.escape(str(x))


def fmt(x, spec: str = ".3e") -> str:
    """A number for a table cell: floats by ``spec``, missing or non-finite values as ``–``,
    anything else as escaped text."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if isinstance(x, float):
        return format(x, spec)
    return esc(x)


def href(path: str | Path) -> str:
    """A relative path as a URL (``/`` separators, special characters quoted)."""
    return esc(quote(Path(path).as_posix() if isinstance(path, Path) else path))


def link(path: str | Path, text: str | None = None) -> str:
    return f'<a href="{href(path)}">{esc(text if text is not None else path)}</a>'


def table(head: list[str] | None, rows: list[list[str]], cls: str = "") -> str:
    """A table of HTML cell fragments (already escaped); ``head`` is escaped here. A cell
    starting with ``<td`` or ``<th`` is used as it is (for classes), else wrapped in ``<td>``."""
    def cell(c):
        return c if c.startswith(("<td", "<th")) else f"<td>{c}</td>"
    thead = ("<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr></thead>"
             if head else "")
    body = "".join("<tr>" + "".join(cell(c) for c in r) + "</tr>\n" for r in rows)
    c = f' class="{esc(cls)}"' if cls else ""
    return f"<table{c}>{thead}<tbody>{body}</tbody></table>"


def kv_table(items: list[tuple[str, object]], spec: str = ".3e") -> str:
    """A two-column table: the name (escaped) and its value (:func:`fmt`)."""
    return table(None, [[f"<th>{esc(k)}</th>", fmt(v, spec)] for k, v in items])


def figure(src: str, caption: str | None = None) -> str:
    """An image (relative path) with its caption (the file name when none is given)."""
    return (f'<figure><img src="{href(src)}" alt="{esc(src)}">'
            f"<figcaption>{esc(caption if caption is not None else src)}</figcaption></figure>")


def figures(names: list[str], captions: dict[str, str] | None = None) -> str:
    return "\n".join(figure(n, (captions or {}).get(n)) for n in names)


def page(title: str, body: str, *, style: str = "", script: str = "", h1: str | None = None
         ) -> str:
    """A whole HTML document: the shared head and stylesheet (plus ``style``), an inline
    ``script`` if any, the ``h1`` (default: the title) and the ``body`` fragment."""
    js = f"<script>{script}</script>" if script else ""
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f"<title>{esc(title)}</title>\n<style>{STYLE}{style}</style>{js}</head><body>\n"
            f"<h1>{esc(h1 if h1 is not None else title)}</h1>\n{body}\n</body></html>\n")


def write_page(path: str | Path, title: str, body: str, **kwargs) -> Path:
    """:func:`page` written atomically to ``path``."""
    return atomic_write_text(path, page(title, body, **kwargs))
