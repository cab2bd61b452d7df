"""A run's report folder: ``index.html`` + PNG figures + the ``.rrd`` recording.

The folder is self-contained (inline CSS, relative links, the recording
copied in) and appears complete or not at all: it is built in a temporary
folder beside ``folder`` and renamed into place. Its ``index.html`` names
vmt as its generator and lists the files the report wrote (``<meta>``): a
report replaces only an empty folder or such an earlier report holding
nothing else (:func:`replace_problem`), never a folder of the user's files.

Examples
--------
>>> from viz.report import Section, Table, write_report       # doctest: +SKIP
>>> write_report("out/report", "Cross pocket, 4 C angles", [
...     Section("Error motions", text="Identified with U95 (k=2).",
...             figures={"error_motions": fig},
...             tables=[Table(["symbol", "identified / µm"], [["EXX", 1.2]])]),
... ], recording="out/run.rrd")
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from core.exceptions import ConfigError, counted


@dataclass(frozen=True)
class Table:
    """A table of the report: column headers and rows of cells (numbers or text).

    Put the unit in the column header (``"U95 / µm"``).
    """

    columns: tuple[str, ...]
    rows: tuple[tuple, ...]
    caption: str = ""

    def __init__(self, columns: Sequence[str], rows: Sequence[Sequence], caption: str = ""):
        cols = tuple(str(c) for c in columns)
        rws = tuple(tuple(r) for r in rows)
        for i, r in enumerate(rws):
            if len(r) != len(cols):
                raise ConfigError(f"table row {i}: {len(r)} cells for {len(cols)} columns")
        object.__setattr__(self, "columns", cols)
        object.__setattr__(self, "rows", rws)
        object.__setattr__(self, "caption", str(caption))


@dataclass(frozen=True)
class Section:
    """One section of the report.

    Attributes
    ----------
    title : str
    text : str
        Plain text (escaped; blank lines separate paragraphs).
    figures : mapping
        ``{name: figure}``; a figure is a matplotlib ``Figure`` (saved as
        ``<name>.png``) or the path of an existing PNG (copied in).
    tables : sequence of Table
    """

    title: str
    text: str = ""
    figures: Mapping[str, object] = field(default_factory=dict)
    tables: Sequence[Table] = ()


def _section(s) -> Section:
    if isinstance(s, Section):
        return s
    if isinstance(s, Mapping):
        d = dict(s)
        d["tables"] = [t if isinstance(t, Table) else Table(**t) for t in d.get("tables", [])]
        try:
            return Section(**d)
        except TypeError as e:
            raise ConfigError(f"section {d.get('title', '?')!r}: {e}") from None
    raise ConfigError(f"sections: expected Section or dict, got {type(s).__name__}")


def _slug(name: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("._")
    return s or "figure"


def _cell(v) -> str:
    if isinstance(v, float):
        return html.escape(f"{v:.4g}")
    if v is None:
        return "–"
    return html.escape(str(v))


_CSS = """
body { font-family: system-ui, sans-serif; max-width: 1100px; margin: 2em auto;
       padding: 0 1em; color: #222; line-height: 1.45; }
h1 { border-bottom: 2px solid #ccc; padding-bottom: .2em; }
h2 { margin-top: 2em; border-bottom: 1px solid #ddd; }
table { border-collapse: collapse; margin: 1em 0; font-size: .92em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: right; }
th { background: #f3f3f3; } td:first-child, th:first-child { text-align: left; }
caption { caption-side: top; text-align: left; font-style: italic; padding: .3em 0; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: .9em; color: #555; }
.toc a { margin-right: 1em; } .rrd { background: #f6f8fa; padding: .6em 1em; }
code { background: #f3f3f3; padding: 0 .25em; }
"""


#: How ``index.html`` says vmt wrote its folder, and which other files the report wrote there.
_META = re.compile(r'<meta name="generator" content="vmt report">\s*'
                   r'<meta name="vmt-report-entries" content="([^"]*)">')


def report_entries(folder) -> list[str] | None:
    """The entries of an earlier report in ``folder`` (``index.html`` first), as its index.html lists
    them; None when ``folder`` holds no index.html that vmt wrote."""
    index = Path(folder) / "index.html"
    try:
        if not index.is_file() or index.is_symlink():
            return None
        with open(index, encoding="utf-8", errors="replace") as f:
            head = f.read(65536)
    except OSError:
        return None
    m = _META.search(head)
    if m is None:
        return None
    try:
        names = json.loads(html.unescape(m.group(1)))
    except ValueError:
        return None
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        return None
    return ["index.html"] + names


def replace_problem(folder) -> str | None:
    """Why an existing ``folder`` may not be replaced whole by a report, or None.

    A report replaces its folder whole (:func:`write_report`), so an existing
    folder must be empty or an earlier report: its ``index.html`` written by
    vmt (a generator ``<meta>`` naming the files the report wrote) and
    nothing else in it, so that a user's file added to a report, a folder
    of the user's own (``--report results/``, also one holding an
    ``index.html`` of its own) or the working folder (``--report .``) is
    never lost with it. A symbolic link is refused: the report would replace
    the link by a folder (and leave the link's old target as it was).
    """
    folder = Path(folder)
    if folder.is_symlink():
        return (f"is a symbolic link (to {os.readlink(folder)}): a report replaces its folder whole and would "
                "replace the link by a folder; give the folder it points to")
    if not folder.is_dir():
        return None
    here = Path.cwd().resolve()
    if folder.resolve() in (here, *here.parents):
        return "is the working folder or one above it: a report replaces its folder whole; give a new folder"
    entries = sorted(e.name for e in os.scandir(folder))
    if not entries:
        return None
    wrote = report_entries(folder)
    if wrote is None:
        return (f"exists and holds {counted(len(entries), 'entry')} but no report of vmt (no index.html vmt wrote): a "
                "report replaces its folder whole; give a new folder (or remove this one)")
    other = [n for n in entries if n not in wrote or not (folder / n).is_file() or (folder / n).is_symlink()]
    if other:
        shown = ", ".join(other[:3]) + (f" and {len(other) - 3} more" if len(other) > 3 else "")
        return (f"is an earlier report but also holds {shown}, which the report did not write: a report "
                "replaces its folder whole; move them out or give a new folder")
    return None


def write_report(folder, title: str, sections: Sequence, *, recording=None,
                 overwrite: bool = True, dpi: int = 110) -> Path:
    """Write a report folder: ``index.html``, one PNG per figure, the recording.

    Parameters
    ----------
    folder : path
        The report folder to create (its parent must exist).
    title : str
        Title of the page.
    sections : sequence of Section (or dicts with the same keys)
    recording : path, optional
        A ``.rrd`` file; copied into the folder and linked, with the
        ``vmt view`` command that opens it.
    overwrite : bool
        Replace an existing report folder (default; only an earlier report of
        vmt holding nothing else, or an empty folder: :func:`replace_problem`);
        otherwise refuse.

    Returns
    -------
    Path
        The report folder.

    Raises
    ------
    ConfigError
        Missing parent folder or recording, existing folder with
        ``overwrite=False``, a figure that is neither a Figure nor a PNG file,
        two figures with the same file name.
    """
    folder = Path(folder)
    secs = [_section(s) for s in sections]
    if not folder.parent.is_dir():
        raise ConfigError(f"report folder {str(folder)!r}: parent folder does not exist")
    if folder.exists() and not overwrite:
        raise ConfigError(f"report folder {str(folder)!r} exists (overwrite=False)")
    if folder.exists() and not folder.is_dir():
        raise ConfigError(f"report folder {str(folder)!r} exists and is not a folder")
    problem = replace_problem(folder)
    if problem:
        raise ConfigError(f"report folder {str(folder)!r} {problem}")
    rrd = None
    if recording is not None:
        rrd = Path(recording)
        if not rrd.is_file():
            raise ConfigError(f"recording {str(rrd)!r}: no such file")

    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=folder.parent))
    try:
        body = _build(tmp, title, secs, rrd, dpi)
        wrote = sorted(e.name for e in os.scandir(tmp))
        body = body.replace("<!--entries-->", '<meta name="generator" content="vmt report">'
                            f'<meta name="vmt-report-entries" content="{html.escape(json.dumps(wrote))}">', 1)
        (tmp / "index.html").write_text(body, encoding="utf-8")
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it 0700
        _swap_into_place(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def _swap_into_place(tmp: Path, folder: Path) -> None:
    """Rename ``tmp`` to ``folder``; an old ``folder`` is moved aside, then removed."""
    if not folder.exists():
        os.replace(tmp, folder)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".old", dir=folder.parent))
    os.rmdir(old)
    os.replace(folder, old)
    try:
        os.replace(tmp, folder)
    except BaseException:
        os.replace(old, folder)  # put the old report back
        raise
    shutil.rmtree(old, ignore_errors=True)


def _build(tmp: Path, title: str, secs: list[Section], rrd: Path | None, dpi: int) -> str:
    from .figures import save_png

    used: set[str] = set()
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8"><!--entries-->',
           f"<title>{html.escape(title)}</title>", f"<style>{_CSS}</style></head><body>",
           f"<h1>{html.escape(title)}</h1>"]
    if secs:
        out.append('<p class="toc">' + "".join(
            f'<a href="#s{i}">{html.escape(s.title)}</a>' for i, s in enumerate(secs)) + "</p>")
    if rrd is not None:
        shutil.copy2(rrd, tmp / rrd.name)
        used.add(rrd.name)
        name = html.escape(rrd.name)
        out.append(f'<p class="rrd">3D recording: <a href="{name}">{name}</a> '
                   f"(rerun; open with <code>vmt view {name}</code>)</p>")
    for i, s in enumerate(secs):
        out.append(f'<h2 id="s{i}">{html.escape(s.title)}</h2>')
        for para in [p for p in str(s.text).split("\n\n") if p.strip()]:
            out.append(f"<p>{html.escape(para.strip())}</p>")
        for t in s.tables:
            if not isinstance(t, Table):
                raise ConfigError(f"section {s.title!r}: tables must be Table objects")
            out.append("<table>")
            if t.caption:
                out.append(f"<caption>{html.escape(t.caption)}</caption>")
            out.append("<tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in t.columns) + "</tr>")
            for r in t.rows:
                out.append("<tr>" + "".join(f"<td>{_cell(v)}</td>" for v in r) + "</tr>")
            out.append("</table>")
        for name, fig in s.figures.items():
            fname = _slug(name) + ".png"
            if fname in used:
                raise ConfigError(f"section {s.title!r}: figure file name {fname!r} used twice")
            used.add(fname)
            if hasattr(fig, "savefig"):
                save_png(fig, tmp / fname, dpi=dpi)
            elif isinstance(fig, (str, os.PathLike)) and Path(fig).is_file():
                shutil.copy2(fig, tmp / fname)
            else:
                raise ConfigError(f"section {s.title!r}: figure {name!r} is neither a "
                                  "matplotlib Figure nor an existing PNG file")
            out.append(f'<figure><img src="{html.escape(fname)}" alt="{html.escape(name)}">'
                       f"<figcaption>{html.escape(name)}</figcaption></figure>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"
