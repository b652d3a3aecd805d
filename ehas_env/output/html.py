"""One self-contained HTML page: headings, paragraphs, tables, preformatted text and PNG figures.

The page opens offline: its style is inline, every figure is embedded as a
``data:image/png;base64`` URI, and it carries no script and no reference to
the network.  Text is escaped (``html.escape``), so nothing in a report's data
becomes markup.  The page is written with the project's atomic writer.

Examples
--------
>>> page = Page("Diagnosis")
>>> page.heading("Verdict")
>>> page.paragraph("explained", id="verdict")
>>> "<h2>Verdict</h2>" in page.html() and "<script" not in page.html()
True
"""
from __future__ import annotations

import base64
import html
from pathlib import Path

#: inline style (no external sheet, no font from the network)
STYLE = ("body{font-family:sans-serif;max-width:70em;margin:1.5em auto;padding:0 1em;color:#222}"
         "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:.2em .5em;"
         "text-align:left;vertical-align:top;font-size:90%}th{background:#eee}td.num{text-align:right;"
         "white-space:nowrap}tr.held td{background:#fff4d6}"
         "pre{background:#f6f6f6;padding:.6em;overflow-x:auto;font-size:85%}img{max-width:100%}"
         "code.command{display:block;background:#f6f6f6;padding:.4em .6em;font-size:90%;overflow-x:auto;"
         "white-space:pre}div.wide{overflow-x:auto}figure{margin:1em 0}figcaption{font-size:90%;color:#444}"
         ".figure{font-size:110%;font-weight:bold}")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


class Page:
    """An HTML page built section by section.

    Parameters
    ----------
    title : str
        The page's title (also its first heading).
    """

    def __init__(self, title: str):
        self.title = title
        self.parts: list[str] = [f"<h1>{html.escape(title)}</h1>"]

    def heading(self, text: str) -> None:
        """Add a section heading.

        Parameters
        ----------
        text : str
            The heading's words.
        """
        self.parts.append(f"<h2>{html.escape(text)}</h2>")

    def paragraph(self, text: str, id: str | None = None, cls: str | None = None, data: dict | None = None) -> None:
        """Add a paragraph of plain text.

        Parameters
        ----------
        text : str
            Its words (escaped).
        id, cls : str, optional
            The element's ``id`` and ``class`` attributes.
        data : dict, optional
            ``data-*`` attributes (name -> value), e.g. a number a test reads back.
        """
        attrs = "".join(f' {k}="{html.escape(str(v))}"' for k, v in (("id", id), ("class", cls)) if v)
        attrs += "".join(f' data-{html.escape(k)}="{html.escape(str(v))}"' for k, v in (data or {}).items())
        self.parts.append(f"<p{attrs}>{html.escape(text)}</p>")

    def subheading(self, text: str) -> None:
        """Add a heading under a section's.

        Parameters
        ----------
        text : str
            The heading's words.
        """
        self.parts.append(f"<h3>{html.escape(text)}</h3>")

    def command(self, text: str, intro: str = "") -> None:
        """Add a shell command the reader can copy and run as written (``<code class="command">``).

        Parameters
        ----------
        text : str
            One command line (escaped).
        intro : str
            Words before it (escaped), e.g. where to run it from.
        """
        lead = f"{html.escape(intro)}<br>" if intro else ""
        self.parts.append(f'<p>{lead}<code class="command">{html.escape(text)}</code></p>')

    def pre(self, text: str) -> None:
        """Add preformatted text (console output, an equation).

        Parameters
        ----------
        text : str
            The text (escaped).
        """
        self.parts.append(f"<pre>{html.escape(text)}</pre>")

    def table(self, header: list[str], rows: list[list], marked: list[bool] | None = None) -> None:
        """Add a table: numbers right-aligned, each row one record.

        Parameters
        ----------
        header : list of str
            Column headings (a number's unit belongs here, e.g. ``Fc [N]``, or in a ``unit`` column).
        rows : list of list
            Cells, shown with ``str`` (None as an empty cell); a cell that reads as a number is right-aligned.
        marked : list of bool, optional
            Rows to highlight (``class="held"``: a run held out for validation), one flag per row.
        """
        def cell(v):
            text = "" if v is None else str(v)
            return f'<td class="num">{html.escape(text)}</td>' if _is_number(text) else f"<td>{html.escape(text)}</td>"

        marked = marked or [False] * len(rows)
        head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
        body = "".join(("<tr class=\"held\">" if m else "<tr>") + "".join(cell(v) for v in r) + "</tr>"
                       for r, m in zip(rows, marked))
        self.parts.append(f'<div class="wide"><table><tr>{head}</tr>{body}</table></div>')

    def figure(self, png: Path, caption: str = "") -> None:
        """Embed a PNG file as a base64 data URI (the page needs no file beside it).

        Parameters
        ----------
        png : Path
            The PNG file.
        caption : str
            Words under it (escaped); also the image's ``alt`` text.
        """
        data = base64.b64encode(Path(png).read_bytes()).decode("ascii")
        alt = html.escape(caption or Path(png).stem)
        self.parts.append(f'<figure><img alt="{alt}" src="data:image/png;base64,{data}">'
                          f"<figcaption>{html.escape(caption)}</figcaption></figure>")

    def html(self) -> str:
        """The whole page.

        Returns
        -------
        str
        """
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<title>{html.escape(self.title)}</title><style>{STYLE}</style></head><body>\n"
                + "\n".join(self.parts) + "\n</body></html>\n")

    def write(self, path) -> Path:
        """Write the page atomically (:func:`ehas_env.output.files.atomic_write_text`).

        Parameters
        ----------
        path : str or Path
            The ``.html`` file.

        Returns
        -------
        Path
        """
        from ehas_env.output.files import atomic_write_text

        return atomic_write_text(path, self.html())
