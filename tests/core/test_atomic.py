"""The atomic writer replaces only regular files, refuses non-finite JSON, and takes back a failed run."""

import json
import os
import socket
import stat

import numpy as np
import pytest

import core.atomic as at
from core.atomic import (RunOutputs, check_output, json_safe, output_kind, same_file, write_json_atomic,
                         write_text_atomic)
from core.exceptions import OutputError, VmtError


def listing(d):
    return sorted(p.name for p in d.iterdir())


def test_new_and_replaced_regular_files(tmp_path):
    p = write_text_atomic(tmp_path / "a" / "b" / "x.txt", "one\n")
    assert p.read_text() == "one\n" and output_kind(p) == "file"
    write_text_atomic(p, "two\n")
    assert p.read_text() == "two\n"
    assert listing(p.parent) == ["x.txt"]                  # no temporary left
    assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~at._umask()


@pytest.mark.parametrize("make, match", [
    (lambda p: p.mkdir(), r"x: is a directory, not a file"),
    (lambda p: p.symlink_to("elsewhere.txt"), r"x: is a symbolic link \(to elsewhere.txt, which does not exist\)"),
    (lambda p: os.mkfifo(p), r"x: is a FIFO \(named pipe\), not a regular file: refusing to replace it"),
])
def test_refuses_to_replace_what_is_not_a_regular_file(tmp_path, make, match):
    p = tmp_path / "x"
    make(p)
    kind = output_kind(p)
    with pytest.raises(OutputError, match=match):
        write_text_atomic(p, "data")
    assert output_kind(p) == kind                         # untouched
    assert listing(tmp_path) == ["x"]                     # no temporary left


def test_link_to_a_file_is_refused_and_both_are_kept(tmp_path):
    (tmp_path / "target.json").write_text('{"keep": 1}\n')
    (tmp_path / "link.json").symlink_to("target.json")
    with pytest.raises(OutputError, match=r"link.json: is a symbolic link \(to target.json, a file\): refusing"):
        write_json_atomic(tmp_path / "link.json", {"new": 2})
    assert (tmp_path / "link.json").is_symlink()
    assert json.loads((tmp_path / "target.json").read_text()) == {"keep": 1}


def test_devices_refused_unless_asked_then_written_through():
    with pytest.raises(OutputError, match=r"/dev/null: is a character device, not a regular file"):
        write_text_atomic("/dev/null", "x")
    assert output_kind("/dev/null") == "character device"
    assert check_output("/dev/null", special=True) == "through"
    write_text_atomic("/dev/null", "x", special=True)
    assert output_kind("/dev/null") == "character device"
    # a full device: the error of the write, not "wrote"
    with pytest.raises(OutputError, match=r"cannot write /dev/full: No space left on device"):
        write_json_atomic("/dev/full", {"a": 1}, special=True)
    assert output_kind("/dev/full") == "character device"


def test_fifo_and_link_to_device_written_through_when_asked(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    rfd = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)          # a reader (does not block)
    try:
        write_text_atomic(fifo, "through the pipe\n", special=True)
        assert os.read(rfd, 100) == b"through the pipe\n"
    finally:
        os.close(rfd)
    assert output_kind(fifo) == "FIFO (named pipe)"
    with pytest.raises(OutputError, match=r"cannot write .*pipe: no process is reading it"):
        write_text_atomic(fifo, "nobody listens", special=True)       # an error, not a hang
    link = tmp_path / "null"
    link.symlink_to("/dev/null")
    write_text_atomic(link, "x", special=True)
    assert link.is_symlink()


def test_socket_and_file_as_folder_refused_even_when_asked(tmp_path):
    s = socket.socket(socket.AF_UNIX)
    try:
        s.bind(str(tmp_path / "sock"))
        with pytest.raises(OutputError, match=r"sock: is a socket, not a regular file"):
            write_text_atomic(tmp_path / "sock", "x", special=True)
    finally:
        s.close()
    (tmp_path / "f").write_text("")
    with pytest.raises(OutputError, match=r"f/x.json: cannot write there: .*f is a file, not a folder"):
        write_text_atomic(tmp_path / "f" / "x.json", "x")
    with pytest.raises(OutputError, match=r"cannot write .*f/sub/x.json: Not a directory"):
        write_text_atomic(tmp_path / "f" / "sub" / "x.json", "x")


def test_operating_system_failures_are_one_line_naming_the_path(tmp_path, monkeypatch):
    def denied(*a, **k):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(at.tempfile, "mkstemp", denied)
    with pytest.raises(OutputError, match=r"^cannot write .*out.json: Permission denied$") as ei:
        write_json_atomic(tmp_path / "out.json", {"a": 1})
    assert isinstance(ei.value, VmtError)
    assert listing(tmp_path) == []


def test_json_non_finite_values_refused_naming_the_key(tmp_path):
    p = tmp_path / "r.json"
    for bad, key in [({"a": {"b": [1.0, float("nan")]}}, r"a.b\[1\] is nan"),
                     ({"rms_um": np.float64("inf")}, r"rms_um is inf"),
                     ({"v": np.array([1.0, -np.inf])}, r"v\[1\] is -inf"),
                     ({"o": object()}, r"o is a object, not a JSON value")]:
        with pytest.raises(OutputError, match=r"refusing to write .*r.json: " + key):
            write_json_atomic(p, bad)
        assert not p.exists()
    # numpy values become plain JSON; a caller meaning "not available" says so with json_safe
    write_json_atomic(p, {"n": np.int64(3), "x": np.float32(0.5), "a": np.arange(2), "ok": np.bool_(True),
                          "u95": json_safe([1.0, float("nan")])})
    assert json.loads(p.read_text()) == {"n": 3, "x": 0.5, "a": [0, 1], "ok": True, "u95": [1.0, None]}


def test_same_file_through_links_and_dots(tmp_path):
    a = tmp_path / "plan.csv"
    a.write_text("x")
    (tmp_path / "l.csv").symlink_to(a)
    assert same_file(a, tmp_path / "l.csv")
    assert same_file(a, tmp_path / "sub" / ".." / "plan.csv")
    assert not same_file(a, tmp_path / "other.csv")


def test_run_outputs_takes_back_what_a_failed_run_wrote(tmp_path):
    keep = tmp_path / "keep.json"
    keep.write_text("old")
    replaced = tmp_path / "replaced.json"
    replaced.write_text("old")
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "mine.txt").write_text("user's")
    (tmp_path / ".rep.before").mkdir()                   # a temporary from before: not this run's
    outs = RunOutputs([keep, replaced, tmp_path / "new.json", folder, tmp_path / "rep",
                       tmp_path / "a" / "b" / "deep.json", None, ""])
    # the run
    write_text_atomic(replaced, "new")
    write_text_atomic(tmp_path / "new.json", "new")
    write_text_atomic(folder / "result.csv", "new")
    (tmp_path / "rep").mkdir()
    (tmp_path / "rep" / "index.html").write_text("half")
    (tmp_path / ".rep.x1y2").mkdir()                      # a hidden temporary left by the report
    write_text_atomic(tmp_path / "a" / "b" / "deep.json", "new")
    removed = outs.remove_written()
    assert keep.read_text() == "old"
    assert (folder / "mine.txt").read_text() == "user's"
    assert listing(tmp_path) == [".rep.before", "keep.json", "out", "replaced.json"]
    assert replaced.read_text() == "old"                  # put back (main removed it: the user's data lost)
    assert listing(folder) == ["mine.txt"]
    assert tmp_path / "a" in removed and tmp_path / ".rep.x1y2" in removed


def test_run_outputs_puts_back_replaced_folders_and_entries_and_commit_drops_the_kept_copies(tmp_path):
    """A report folder replaced whole, an entry of a folder replaced or removed, a file removed: each
    back as it was after a failed run (main lost them all); after a run that succeeded the kept
    copies are dropped and the new outputs stay."""
    import shutil

    rep, comp, j = tmp_path / "rep", tmp_path / "comp", tmp_path / "j.json"
    rep.mkdir()
    (rep / "index.html").write_text("old page")
    (rep / "sub").mkdir()
    (rep / "sub" / "f.png").write_text("old fig")
    comp.mkdir()
    (comp / "X.comp").write_text("old X")
    (comp / "Y.comp").write_text("old Y")
    j.write_text("old json")
    outs = RunOutputs([rep, comp, j])
    assert os.stat(j).st_nlink == 1                       # kept as a copy, not a second name of it
    new = tmp_path / ".rep.new"
    new.mkdir()
    (new / "index.html").write_text("new page")
    shutil.rmtree(rep)
    os.replace(new, rep)                                  # the report's swap
    write_text_atomic(comp / "X.comp", "new X")
    (comp / "Y.comp").unlink()
    write_text_atomic(comp / "Z.comp", "new Z")
    j.unlink()
    outs.remove_written()
    assert (rep / "index.html").read_text() == "old page" and (rep / "sub" / "f.png").read_text() == "old fig"
    assert listing(comp) == ["X.comp", "Y.comp"] and (comp / "X.comp").read_text() == "old X"
    assert (comp / "Y.comp").read_text() == "old Y" and j.read_text() == "old json"
    assert listing(tmp_path) == ["comp", "j.json", "rep"]
    outs = RunOutputs([rep, j])
    write_text_atomic(j, "new json")
    outs.commit()
    assert listing(tmp_path) == ["comp", "j.json", "rep"] and j.read_text() == "new json"
    assert os.stat(rep / "index.html").st_nlink == 1


def test_run_outputs_survives_a_writer_that_writes_in_place(tmp_path):
    """A writer that opens an output and rewrites it in place (truncate, write, fail half way),
    a file and an entry of an output folder: after the failed run both hold the user's content
    again. On main the kept copy was a hard link, the same inode: truncating the output truncated
    it too, and the failed run's half-written file was what got 'put back'."""
    j, comp = tmp_path / "j.json", tmp_path / "comp"
    j.write_text("user's json")
    comp.mkdir()
    (comp / "X.comp").write_text("user's X")
    outs = RunOutputs([j, comp])
    for p in (j, comp / "X.comp"):
        with open(p, "w") as f:                          # in place: the same inode, truncated
            f.write("ha")                               # ... and the run fails here
    outs.remove_written()
    assert j.read_text() == "user's json" and (comp / "X.comp").read_text() == "user's X"
    assert listing(tmp_path) == ["comp", "j.json"] and listing(comp) == ["X.comp"]


def test_run_outputs_keeps_everything_when_nothing_was_written(tmp_path):
    (tmp_path / "x.json").write_text("old")
    outs = RunOutputs([tmp_path / "x.json", tmp_path / "missing" / "y.json"])
    assert outs.remove_written() == []
    assert listing(tmp_path) == ["x.json"]


def test_dev_stdout_is_written_through_never_replaced(tmp_path):
    """`--out /dev/stdout >> file` and `| reader`: the text lands where the shell sent stdout, after
    what is there, and /dev/stdout stays the link it is. (As root, the old writer replaced
    /dev/stdout by a regular file.)"""
    import subprocess
    import sys

    code = ("import sys; from core.atomic import write_text_atomic; "
            "write_text_atomic('/dev/stdout', 'through\\n', special=True)")
    out = tmp_path / "o.txt"
    out.write_text("kept\n")
    with open(out, "a") as f:
        subprocess.run([sys.executable, "-c", code], stdout=f, check=True)
    assert out.read_text() == "kept\nthrough\n"
    assert os.path.islink("/dev/stdout")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout == "through\n"
    with pytest.raises(OutputError, match="symbolic link"):
        write_text_atomic("/dev/stdout", "x")             # not asked: refused, never replaced
    assert os.path.islink("/dev/stdout")


@pytest.mark.parametrize("kind, tool, pack", [
    ("gzip", "gzip", ["gzip", "-c"]), ("bzip2", "bzip2", ["bzip2", "-c"]), ("xz", "xz", ["xz", "-c"]),
    ("zstd", "zstd", ["zstd", "-q", "-c"]), ("zip", "unzip", None)])
def test_not_text_problem_names_the_compression_and_a_command_that_decompresses_it(tmp_path, kind, tool, pack):
    """A compressed file under a name that does not say so (a space in it, no .gz/.xz suffix: the
    old advice 'gunzip -k FILE' refuses such a name, 'unknown suffix'): the message names the
    format, and its command, run by a POSIX shell as printed, writes the original bytes."""
    import shlex
    import shutil
    import subprocess
    import zipfile

    if shutil.which(tool) is None or (pack and shutil.which(pack[0]) is None):
        pytest.skip(f"{tool} not installed")
    body = b"setup,target\ns1,1\n"
    p = tmp_path / "my log.csv"
    if pack is None:
        with zipfile.ZipFile(p, "w") as z:
            z.writestr("log.csv", body)
    else:
        p.write_bytes(subprocess.run(pack, input=body, capture_output=True, check=True).stdout)
    data = p.read_bytes()
    with pytest.raises(UnicodeDecodeError) as e:
        data.decode("utf-8")
    msg = at.not_text_problem(p, data[:8], e.value)
    prefix = f"{kind}-compressed, not text: decompress it first ("
    assert msg.startswith(prefix) and msg.endswith(f" > {shlex.quote(str(p) + '.txt')})")
    subprocess.run(["sh", "-c", msg[len(prefix):-1]], cwd=tmp_path, check=True)
    assert (tmp_path / "my log.csv.txt").read_bytes() == body


def test_not_text_problem_says_the_byte_counted_from_the_file_start():
    """Not compressed: 'not UTF-8 text (REASON at byte N)', N from the file's first byte (the decoded
    bytes start at ``offset``); bad bytes away from the file's start are not taken for a magic number."""
    with pytest.raises(UnicodeDecodeError) as e:
        b"ab\xffc".decode("utf-8")
    assert at.not_text_problem("f.csv", b"ab\xffc", e.value) == "not UTF-8 text (invalid start byte at byte 2)"
    assert at.not_text_problem("f.csv", b"", e.value, 100) == "not UTF-8 text (invalid start byte at byte 102)"
    with pytest.raises(UnicodeDecodeError) as e:
        b"\x1f\x8b\x08".decode("utf-8")  # a gzip header, but given as bytes not at the file's start
    assert at.not_text_problem("f.csv", b"", e.value, 40) == "not UTF-8 text (invalid start byte at byte 41)"
