"""Outputs that appear complete or not at all, and never replace what is not a file.

Three promises, for every file vmt writes:

1. **Atomic.** A file is written to a temporary file beside it, fsynced and
   renamed into place: a reader sees the old file or the new one, never half
   of one; a failure leaves the old file and no temporary behind.
2. **Only regular files are replaced.** An output path that is a directory,
   a symbolic link, a device, a FIFO or a socket is refused
   (:class:`~core.exceptions.OutputError`), so ``--json /dev/full`` never
   turns the device into a file and a link is never silently replaced by a
   file. With ``special=True`` (the caller states that the user named a
   device or a pipe as the output) a character device or FIFO, also one
   reached through a link, and ``/dev/stdout`` (whatever the shell made
   of it) are written through instead, never replaced; a block device or
   socket never is.
3. **Honest numbers.** :func:`write_json_atomic` refuses NaN and infinities
   (JSON has neither) and names the key; a caller that means "not
   available" converts such values to ``None`` itself (:func:`json_safe`).

:class:`RunOutputs` removes what a failed run wrote (files, report folders,
leftover temporaries) and puts back the earlier outputs it replaced, for the
command line to use; :func:`same_file`
finds an output that would overwrite an input.
"""

from __future__ import annotations

import errno
import json
import math
import os
import shutil
import stat
import sys
import tempfile
from pathlib import Path

from .exceptions import OutputError

#: What :func:`output_kind` calls each kind of file.
_KINDS = ((stat.S_ISDIR, "directory"), (stat.S_ISCHR, "character device"),
          (stat.S_ISBLK, "block device"), (stat.S_ISFIFO, "FIFO (named pipe)"),
          (stat.S_ISSOCK, "socket"), (stat.S_ISREG, "file"))
#: Kinds that ``special=True`` writes through (never replaces).
THROUGH_KINDS = ("character device", "FIFO (named pipe)")


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def _kind_of_mode(mode: int) -> str:
    for test, name in _KINDS:
        if test(mode):
            return name
    return "special file"  # pragma: no cover - no other kinds on POSIX


def output_kind(path) -> str:
    """What ``path`` is now: ``"missing"``, ``"file"``, ``"directory"``,
    ``"symbolic link"``, ``"character device"``, ``"block device"``,
    ``"FIFO (named pipe)"`` or ``"socket"`` (a link is not followed)."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return "missing"
    except NotADirectoryError:
        return "missing"
    if stat.S_ISLNK(st.st_mode):
        return "symbolic link"
    return _kind_of_mode(st.st_mode)


def own_descriptor(path) -> int | None:
    """N when ``path`` names an open descriptor of this process (``/dev/stdout``,
    ``/dev/fd/N``, ``/proc/self/fd/N``), else None."""
    q = str(path)
    for t in (q, os.path.join(os.path.dirname(q), os.readlink(q)) if os.path.islink(q) else None):
        if t is None:
            continue
        d = os.path.realpath(os.path.dirname(t))
        if d == os.path.realpath("/proc/self/fd") and os.path.basename(t).isdigit():
            return int(os.path.basename(t))
    return None


def check_output(path, *, special: bool = False) -> str:
    """Refuse an output path vmt must not replace; say how it will be written.

    Parameters
    ----------
    path : path-like
    special : bool
        The user named a device or a pipe as the output: write through a
        character device or FIFO (also one a link points to) instead of
        refusing it.

    Returns
    -------
    str
        ``"replace"`` (a regular file, or nothing yet: written atomically) or
        ``"through"`` (a character device or FIFO, written in place).

    Raises
    ------
    OutputError
        The path is a directory, a link (to anything but a device or FIFO
        with ``special``), a device or FIFO without ``special``, a block
        device, a socket, or its folder is not a folder.
    """
    p = Path(path)
    kind = output_kind(p)
    if special and kind == "symbolic link" and own_descriptor(p) is not None:
        return "through"        # /dev/stdout and kin: the shell's redirection, whatever it is
    if kind in ("missing", "file"):
        parent = p.parent
        pk = output_kind(parent) if str(parent) not in ("", ".") else "directory"
        if pk not in ("missing", "directory", "symbolic link"):
            raise OutputError(f"{p}: cannot write there: {parent} is a {pk}, not a folder")
        return "replace"
    if kind == "symbolic link":
        target = os.readlink(p)
        try:
            real = _kind_of_mode(os.stat(p).st_mode)
        except OSError:
            real = "missing"
        if special and real in THROUGH_KINDS:
            return "through"
        what = "which does not exist" if real == "missing" else f"a {real}"
        raise OutputError(f"{p}: is a symbolic link (to {target}, {what}): refusing to replace a link "
                          "with a file; give the path it points to")
    if kind == "directory":
        raise OutputError(f"{p}: is a directory, not a file")
    if special and kind in THROUGH_KINDS:
        return "through"
    raise OutputError(f"{p}: is a {kind}, not a regular file: refusing to replace it"
                      + (" (vmt writes through only a character device or a FIFO)" if special else ""))


def write_text_atomic(path, text: str, *, special: bool = False) -> Path:
    """Write ``text`` to ``path`` via a temporary file renamed into place.

    The file gets the ordinary permissions (0666 less the umask), it is
    fsynced before the rename, and a failure leaves any previous file as
    it was and no temporary file behind. Folders missing on the way are
    created.

    Parameters
    ----------
    path : path-like
    text : str or iterable of str
        Written as UTF-8; an iterable piece by piece (a large text never whole in memory).
    special : bool
        Write through a character device or FIFO (see :func:`check_output`).

    Raises
    ------
    OutputError
        Refused by :func:`check_output`, or the operating system failed
        (permission denied, disk full, ...): one line naming the path and why.
    """
    p = Path(path)
    if check_output(p, special=special) == "through":
        own = own_descriptor(p)
        try:
            if own is not None:
                # /dev/stdout and kin: this process's own descriptor, the shell's redirection
                # (a pipe, a file opened with > or >>): write on it, sharing its offset
                for s in (sys.stdout, sys.stderr):
                    if s is not None:
                        s.flush()
                fd = os.dup(own)
            else:
                # non-blocking open: a FIFO nobody reads is an error, not a hang
                fd = os.open(p, os.O_WRONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
        except OSError as e:
            why = "no process is reading it" if e.errno == errno.ENXIO else (e.strerror or str(e))
            raise OutputError(f"cannot write {p}: {why}") from None
        try:
            os.set_blocking(fd, True)
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
                f.writelines([text] if isinstance(text, str) else text)
        except BrokenPipeError:
            raise                   # the reader left: the caller ends quietly
        except OSError as e:
            raise OutputError(f"cannot write {p}: {e.strerror or e}") from None
        return p
    tmp = None
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", dir=p.parent)
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            f.writelines([text] if isinstance(text, str) else text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        check_output(p)  # it may have changed since: still never replace a non-file
        os.replace(tmp, p)
    except OSError as e:
        raise OutputError(f"cannot write {p}: {e.strerror or e}") from None
    finally:
        if tmp is not None and os.path.lexists(tmp):
            os.unlink(tmp)
    return p


def json_safe(o):
    """``o`` with NaN and infinities as None: for a caller that means "not available"."""
    if isinstance(o, dict):
        return {k: json_safe(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [json_safe(v) for v in o]
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return o


def _plain(o, where: str, path):
    """``o`` as plain JSON types (numpy scalars and arrays converted); refuse non-finite floats."""
    if isinstance(o, dict):
        return {str(k): _plain(v, f"{where}.{k}" if where else str(k), path) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_plain(v, f"{where}[{i}]", path) for i, v in enumerate(o)]
    tolist = getattr(o, "tolist", None)
    if tolist is not None and not isinstance(o, (str, bytes)):  # numpy scalar or array
        return _plain(tolist(), where, path)
    if isinstance(o, bool) or o is None or isinstance(o, (str, int)):
        return o
    if isinstance(o, float):
        if not math.isfinite(o):
            raise OutputError(f"refusing to write {path}: {where or 'the value'} is {o} "
                              "(not a number JSON can hold; the result is not valid)")
        return float(o)
    raise OutputError(f"refusing to write {path}: {where or 'the value'} is a {type(o).__name__}, "
                      "not a JSON value")


def json_text(obj, path="the output") -> str:
    """``obj`` as indented JSON text, or :class:`OutputError` naming a NaN or infinite value's key.

    To check a result before anything of a run is written (then write the
    text with :func:`write_text_atomic`).
    """
    return json.dumps(_plain(obj, "", path), indent=2, allow_nan=False) + "\n"


def write_json_atomic(path, obj, *, special: bool = False) -> Path:
    """Write ``obj`` as indented JSON, atomically.

    Raises
    ------
    OutputError
        ``obj`` holds NaN or an infinity (the message names the key), or a
        value JSON cannot hold; or :func:`write_text_atomic` refuses.
    """
    return write_text_atomic(path, json_text(obj, path), special=special)


# ---------------------------------------------------------------------------
# inputs versus outputs


def input_problem(path, noun: str = "file") -> str | None:
    """Why ``path`` cannot be read as an input (``"no such file"``, ``"is a directory, not a
    NOUN"``, ``"cannot read: Permission denied"``, ...), or None when it is a readable file or pipe."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "no such file"
    except OSError as e:
        return f"cannot read: {e.strerror or e}"
    if stat.S_ISDIR(st.st_mode):
        return f"is a directory, not a {noun}"
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISFIFO(st.st_mode)):
        return f"is a device or socket, not a {noun}"
    if not os.access(path, os.R_OK):
        return f"cannot read: {os.strerror(errno.EACCES)}"
    return None


#: Magic numbers of compressed files handed to vmt where it reads text: (first bytes, format, the
#: command that writes the decompressed bytes on stdout, whatever the file's name ends with).
_COMPRESSED = ((b"\x1f\x8b", "gzip", "gzip -dc"), (b"BZh", "bzip2", "bzip2 -dc"), (b"\xfd7zXZ\x00", "xz", "xz -dc"),
               (b"(\xb5/\xfd", "zstd", "zstd -dc"), (b"PK\x03\x04", "zip", "unzip -p"))


def not_text_problem(path, head: bytes, err: UnicodeDecodeError, offset: int = 0) -> str:
    """Why the file ``path`` is not text, in one line, for every reader of vmt's text formats
    (plain UTF-8, docs/formats.md) that failed to decode it with ``err``.

    ``head`` is the file's first bytes (b"" where the bad bytes are not at its start): a UTF-16
    byte-order mark there gives a conversion command (:func:`head_problem`), a compressed
    format's magic number ``"gzip-compressed, not text: decompress it first (gzip -dc
    log.csv.gz > log.csv.gz.txt)"``, a command that works whatever the name ends with (``gunzip
    -k`` refuses a name without ``.gz``), the paths quoted for a POSIX shell. Else ``"not UTF-8
    text (REASON at byte N)"``, N counted from the file's first byte (``offset`` is where the
    bytes ``err`` decoded start in the file).
    """
    return head_problem(path, head) or f"not UTF-8 text ({err.reason} at byte {offset + err.start})"


def head_problem(path, head: bytes) -> str | None:
    """:func:`not_text_problem`'s words for a file whose first bytes ``head`` show it is not UTF-8
    text as a whole (a compressed format's magic number, or a UTF-16 byte-order mark, as Windows
    PowerShell 5.1's ``>`` writes), or None. Also for readers that tolerate stray bytes (a
    controller's transcript, decoded with replacement) but not a whole file in another form."""
    import shlex

    src = shlex.quote(str(path))
    dst = shlex.quote(f"{path}.txt")
    for magic, kind, cmd in _COMPRESSED:
        if head.startswith(magic):
            return f"{kind}-compressed, not text: decompress it first ({cmd} {src} > {dst})"
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        return f"UTF-16 text, not UTF-8: convert it first (iconv -f UTF-16 -t UTF-8 {src} > {dst})"
    return None


def same_file(a, b) -> bool:
    """True when paths ``a`` and ``b`` name the same file (links and ``..`` resolved)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


# ---------------------------------------------------------------------------
# removing what a failed run wrote


def _ident(path) -> tuple | None:
    try:
        st = os.lstat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_mtime_ns, st.st_size, stat.S_IFMT(st.st_mode))


def _entries(d: Path) -> dict:
    try:
        return {e.name: _ident(e.path) for e in os.scandir(d)}
    except OSError:
        return {}


def _remove(path: Path) -> None:
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink()
    except FileNotFoundError:
        pass


class RunOutputs:
    """The outputs a run may write, and how to take them back if it fails.

    Give the paths before the run (files or folders, e.g. ``--json``,
    ``--report``, ``--out``). An output that exists then (a regular file or
    a folder) is kept aside: a hidden folder ``.vmt-kept.NAME.*`` beside it
    holds a copy of the file, or of each file of the folder. A copy, not a
    second name (a hard link): vmt's writers rename a new file over an
    output (:func:`write_text_atomic`), which leaves a link's content alone,
    but a writer that opens the output and writes in place (truncating it)
    would write through a link into the kept content too, and a failed run
    would then "put back" its own half-written file; with a copy nothing a
    run does at the output reaches what is kept. The price: the bytes of
    the earlier outputs are copied once per run (``shutil.copy2``: a
    48.5 MB probe log of 2e5 rows kept in 0.16 s at load 12 on 2 cores).

    :meth:`remove_written` (the run failed) removes what the run created or
    changed there: a new file or folder, new or replaced entries of a
    folder that existed, the hidden temporaries ``.NAME.*`` it left beside
    an output, and the folders it created on the way to one; and it puts
    back what the run replaced or removed from the kept copy, so a failed
    run loses none of the user's earlier outputs. :meth:`commit` (the run
    succeeded) drops the kept copies.

    Examples
    --------
    >>> outs = RunOutputs(["rep.json", "report/"])   # doctest: +SKIP
    >>> try:
    ...     run()
    ... except BaseException:
    ...     outs.remove_written()
    ...     raise
    >>> outs.commit()                                # doctest: +SKIP
    """

    def __init__(self, paths):
        self.paths = [Path(p) for p in paths if p not in (None, "")]
        self._before = {}
        self._kept = {}
        try:
            for p in self.paths:
                ident = _ident(p)
                inside = _entries(p) if ident is not None and stat.S_ISDIR(ident[4]) else None
                siblings = {k for k in _entries(p.parent) if k.startswith(f".{p.name}.")}
                first_new = None
                q = p.parent
                while str(q) not in ("", ".", "/") and _ident(q) is None:
                    first_new = q
                    q = q.parent
                self._before[p] = (ident, inside, siblings, first_new)
                if ident is not None and (stat.S_ISREG(ident[4]) or stat.S_ISDIR(ident[4])) and p not in self._kept:
                    keep = Path(tempfile.mkdtemp(prefix=f".vmt-kept.{p.name}.", dir=p.parent))
                    self._kept[p] = keep
                    if inside is None:  # copies, not links: an in-place writer cannot reach them (class doc)
                        shutil.copy2(p, keep / p.name, follow_symlinks=False)
                    else:
                        shutil.copytree(p, keep / p.name, symlinks=True, copy_function=shutil.copy2)
        except BaseException:
            self.commit()
            raise

    def commit(self) -> None:
        """The run succeeded: drop the kept copies of the earlier outputs."""
        for keep in self._kept.values():
            shutil.rmtree(keep, ignore_errors=True)
        self._kept = {}

    def remove_written(self) -> list[Path]:
        """Remove what the run wrote at the outputs and put back what it replaced; return the
        paths removed."""
        removed = []
        for p, (ident, inside, siblings, first_new) in self._before.items():
            now = _ident(p)
            kept = self._kept.get(p)
            old = kept / p.name if kept is not None else None
            if now is not None:
                if ident is None or now[:2] != ident[:2] or (inside is None and now != ident):
                    _remove(p)          # new, or a different file/folder in its place
                    removed.append(p)
                elif inside is not None:  # the same folder: take back its new or changed entries
                    for name, e in _entries(p).items():
                        if inside.get(name) != e:
                            _remove(p / name)
                            removed.append(p / name)
                    for name in inside:   # and put back those it replaced or removed
                        if old is not None and name not in _entries(p) and os.path.lexists(old / name):
                            os.replace(old / name, p / name)
            if old is not None and not os.path.lexists(p) and os.path.lexists(old):
                os.replace(old, p)      # the earlier file or folder, as it was
            for name in _entries(p.parent):
                if name.startswith(f".{p.name}.") and name not in siblings:
                    _remove(p.parent / name)
                    removed.append(p.parent / name)
            if first_new is not None:
                q = p.parent
                while True:         # folders made on the way, if the run left nothing else there
                    try:
                        q.rmdir()
                    except OSError:
                        break
                    removed.append(q)
                    if q == first_new:
                        break
                    q = q.parent
        self.commit()
        return removed
