"""The report's HTML: one self-contained page (inline style, no scripts, no external links)
with the pictures as files beside it.

Built from plain pieces (headline cards, key/value tables, row tables, figures with
captions) so the same numbers always give the same bytes: no dates, no wall-clock times, no
absolute paths.
"""
from __future__ import annotations

from html import escape

STYLE = """
body { font-family: "DejaVu Sans", Verdana, Arial, sans-serif; margin: 0; color: #1d1d1d; background: #f4f5f7; }
header { background: #243447; color: white; padding: 18px 32px 14px; }
header h1 { margin: 0 0 4px; font-size: 26px; }
header p { margin: 0; color: #c9d3de; }
main { max-width: 1320px; margin: 0 auto; padding: 8px 24px 40px; }
section { background: white; border-radius: 6px; padding: 10px 20px 16px; margin: 18px 0;
          box-shadow: 0 1px 3px rgba(0,0,0,0.12); }
h2 { font-size: 20px; margin: 8px 0 10px; border-bottom: 2px solid #e3e6ea; padding-bottom: 4px; }
h3 { font-size: 15px; margin: 14px 0 6px; }
.cards { display: flex; flex-wrap: wrap; gap: 12px; margin-top: 18px; }
.card { background: white; border-radius: 6px; padding: 10px 16px; min-width: 170px; flex: 1;
        box-shadow: 0 1px 3px rgba(0,0,0,0.12); border-top: 4px solid #2c6fbb; }
.card.bad { border-top-color: #d62728; }
.card .k { font-size: 12px; color: #5b6470; text-transform: uppercase; letter-spacing: 0.04em; }
.card .v { font-size: 24px; font-weight: bold; margin: 2px 0; }
.card .n { font-size: 12px; color: #5b6470; }
.tables { display: flex; flex-wrap: wrap; gap: 18px; }
.tables > div { flex: 1; min-width: 280px; }
table { border-collapse: collapse; font-size: 13px; margin: 4px 0 8px; }
th, td { padding: 3px 10px 3px 0; text-align: left; vertical-align: top; border-bottom: 1px solid #eceef1; }
.tables th { white-space: nowrap; }
table.rows th { background: #f0f2f5; padding-left: 6px; }
table.rows td { padding-left: 6px; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 8px 0 4px; }
figure img { max-width: 100%; height: auto; border: 1px solid #e3e6ea; }
figcaption { font-size: 13px; color: #444; margin-top: 4px; max-width: 1100px; }
p.note { font-size: 13px; color: #555; }
footer { font-size: 12px; color: #666; text-align: center; padding: 10px; }
"""


def card(key: str, value: str, note: str = "", bad: bool = False, ident: str = "") -> str:
    """A headline figure."""
    i = f' id="{escape(ident)}"' if ident else ""
    return (f'<div class="card{" bad" if bad else ""}"{i}><div class="k">{escape(key)}</div>'
            f'<div class="v">{escape(value)}</div><div class="n">{escape(note)}</div></div>')


def key_values(title: str, rows, ident: str = "") -> str:
    """A two-column table (name, value) under a small heading."""
    i = f' id="{escape(ident)}"' if ident else ""
    body = "".join(f"<tr><th>{escape(str(k))}</th><td>{escape(str(v))}</td></tr>" for k, v in rows)
    return f"<div><h3>{escape(title)}</h3><table{i}>{body}</table></div>"


def row_table(header, rows, ident: str = "", numeric=None) -> str:
    """A table with a header row; ``numeric``: indices of right-aligned columns."""
    numeric = set(numeric or ())
    i = f' id="{escape(ident)}"' if ident else ""
    head = "".join(f"<th>{escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f'<td{" class=num" if j in numeric else ""}>{escape(str(c))}</td>'
                                    for j, c in enumerate(r)) + "</tr>" for r in rows)
    return f'<table class="rows"{i}><tr>{head}</tr>{body}</table>'


def picture(src: str, alt: str, caption: str, size) -> str:
    """An image file beside the page (relative ``src``) with its caption."""
    w, h = size
    return (f'<figure><img src="{escape(src)}" alt="{escape(alt)}" width="{w}" height="{h}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


def section(ident: str, title: str, *parts: str) -> str:
    return f'<section id="{escape(ident)}"><h2>{escape(title)}</h2>{"".join(parts)}</section>'


def note(text: str) -> str:
    return f'<p class="note">{escape(text)}</p>'


def page(title: str, subtitle: str, cards: list, sections: list, footer: str) -> str:
    """The whole document."""
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
            f"<header><h1>{escape(title)}</h1><p>{escape(subtitle)}</p></header>\n<main>\n"
            f'<div class="cards">{"".join(cards)}</div>\n' + "\n".join(sections)
            + f"\n</main>\n<footer>{escape(footer)}</footer>\n</body>\n</html>\n")
