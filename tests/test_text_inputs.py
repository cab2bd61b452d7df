"""Every reader of vmt's text formats (plain UTF-8, docs/formats.md) says the same thing, in one
line, of a file that is not text: ``core.atomic.not_text_problem`` (a compressed file: which
compression and how to decompress it; else the first bad byte, counted from the file's start)."""

import gzip

import pytest

from core.exceptions import VmtError


def _keyreader(p):
    from core.exceptions import ConfigError
    from core.keyreader import read_text_file

    return read_text_file(p, ConfigError, "file")


def _positioning(p):
    from core.positioning import read_positioning_log

    return read_positioning_log(p)


def _probelog(p):
    from core.probelog import read_probe_log

    return read_probe_log(p)


def _recover(p):
    from hardware.campaign import recover_log

    return recover_log(p, None)  # the plan is looked at only once the file is text


def _bar_calibration(p):  # vmt scenario mfb-3axis --bar-calibration FILE
    from scenarios.mfb import read_bar_calibration

    return read_bar_calibration(p)


def _bench_results(p):  # vmt bench --from-json FILE
    from scenarios.bench.table import read_results

    return read_results(p)


def _study_machine(p):  # a regression study's machine file: machine = "FILE"
    from scenarios.regress import loads_study

    return loads_study(f'identification = "iso230-2"\nmachine = "{p.name}"\nseeds = [1]\n'
                       "[accept.mean]\nwithin_u95 = 1.0\n", "<study>", p.parent)


READERS = {"keyreader": (_keyreader, ""), "positioning": (_positioning, ""), "probelog": (_probelog, ""),
           "recover_log": (_recover, ""), "bar_calibration": (_bar_calibration, "bar calibration "),
           "bench_results": (_bench_results, ""), "study_machine": (_study_machine, "")}


@pytest.mark.parametrize("reader", sorted(READERS))
def test_a_file_that_is_not_text_is_refused_in_the_same_words_by_every_reader(tmp_path, reader):
    read, prefix = READERS[reader]
    body = b"setup,target,t_s\ns1,1,0\n"
    k = 20  # inside the data row
    bad = tmp_path / "bad.csv"
    bad.write_bytes(body[:k] + b"\xff" + body[k:])
    with pytest.raises(VmtError) as e:
        read(bad)
    assert str(e.value) == f"{prefix}{bad}: not UTF-8 text (invalid start byte at byte {k})"
    if reader in ("positioning", "probelog"):  # the readers that take a byte-order mark
        bad.write_bytes(b"\xef\xbb\xbf" + body[:k] + b"\xff" + body[k:])
        with pytest.raises(VmtError) as e:
            read(bad)
        assert str(e.value) == f"{prefix}{bad}: not UTF-8 text (invalid start byte at byte {k + 3})"
    packed = tmp_path / "log.csv"  # compressed, under a name that does not say so
    packed.write_bytes(gzip.compress(body))
    with pytest.raises(VmtError) as e:
        read(packed)
    assert str(e.value) == (f"{prefix}{packed}: gzip-compressed, not text: decompress it first "
                            f"(gzip -dc {packed} > {packed}.txt)")
    wide = tmp_path / "wide.csv"  # UTF-16 with its byte-order mark (Windows PowerShell 5.1's `>`)
    wide.write_bytes(body.decode().encode("utf-16"))
    with pytest.raises(VmtError) as e:
        read(wide)
    assert str(e.value) == (f"{prefix}{wide}: UTF-16 text, not UTF-8: convert it first "
                            f"(iconv -f UTF-16 -t UTF-8 {wide} > {wide}.txt)")


def test_the_commands_say_it_in_one_line(tmp_path, capsys):
    """The two commands the reviewer found saying 'not JSON (utf-8 codec ...)' of a gzip file:
    exit 2, one line naming the compression (before any simulation or README change)."""
    from scenarios.cli import main

    cal = tmp_path / "cal.json.gz"
    cal.write_bytes(gzip.compress(b'{"format": "vmt-bar-calibration/1"}'))
    readme = tmp_path / "README.md"
    readme.write_text("x\n")
    comp = tmp_path / "comp"  # vmt scenario --apply-comp DIR: its volumetric table, gzip-compressed (was a traceback)
    comp.mkdir()
    (comp / "mfb-3axis-comp.json").write_bytes(gzip.compress(b"{}"))
    for argv, bad in ((["scenario", "mfb-3axis", "--bar-calibration", str(cal)], cal),
                      (["bench", "--from-json", str(cal), "--readme", str(readme)], cal),
                      (["scenario", "mfb-3axis", "--apply-comp", str(comp)], comp / "mfb-3axis-comp.json")):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{bad}: gzip-compressed, not text: decompress it first (gzip -dc " in err
    assert readme.read_text() == "x\n"


def test_apply_comp_names_the_file_and_key_of_a_malformed_table(tmp_path, capsys):
    """review32d F1: a vmt-comp/1 table with a string in 'identified' was a traceback (exit 1); now one line
    naming the file and the key, exit 2, before any simulation."""
    import json

    from scenarios.cli import main

    comp = tmp_path / "comp"
    comp.mkdir()
    from core.volumetric import MOTION, SQUARENESS

    errs = {s: {"identified": [0.0, 1.0], "nodes_mm": [0.0, 100.0]} for s in MOTION}
    errs.update({s: {"identified": [1.0]} for s in SQUARENESS})
    errs["EXX"]["identified"] = "abc"
    (comp / "mfb-3axis-comp.json").write_text(json.dumps({"format": "vmt-comp/1", "errors": errs}))
    capsys.readouterr()
    assert main(["scenario", "mfb-3axis", "--apply-comp", str(comp)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert (f"{comp / 'mfb-3axis-comp.json'}: errors.EXX.identified must be a number or a list of numbers, "
            "got 'abc'") in err, err


def test_a_controller_transcript_that_is_not_text_is_named_as_such(tmp_path, capsys):
    """A controller's transcript tolerates stray bytes (decoded with replacement: serial noise in a
    line that is not a probe report), but a whole transcript that is compressed or UTF-16 is refused
    in the same words as every other reader, not as "no probe reports" (session-9 finding), through
    `vmt import grbl` too (exit 2, one line); and a transcript on a pipe is read."""
    import subprocess
    import sys

    from hardware.transcript import read_transcript
    from scenarios.cli import main

    body = b"ok\n[PRB:1.000,2.000,3.000:1]\nok\n"
    plain = tmp_path / "plain.txt"
    plain.write_bytes(body[:2] + b"\xff" + body[2:])  # a stray byte outside the report: tolerated
    pos, touched, _, _ = read_transcript(plain)
    assert pos.tolist() == [[1.0, 2.0, 3.0]] and touched.tolist() == [True]
    packed, wide = tmp_path / "session.txt", tmp_path / "ps.txt"
    packed.write_bytes(gzip.compress(body))
    wide.write_bytes(body.decode().encode("utf-16"))
    plan = tmp_path / "plan.csv"
    assert main(["simulate", "cross-pocket", "--plan-only", "--no-collision-check", "--c-angles-deg", "0",
                 "--out", str(plan)]) == 0
    for bad, words in ((packed, f"gzip-compressed, not text: decompress it first (gzip -dc {packed} > {packed}.txt)"),
                       (wide, f"UTF-16 text, not UTF-8: convert it first (iconv -f UTF-16 -t UTF-8 {wide} > {wide}.txt)")):
        with pytest.raises(VmtError) as e:
            read_transcript(bad)
        assert str(e.value) == f"{bad}: {words}"
        capsys.readouterr()
        assert main(["import", "grbl", str(bad), "--plan", str(plan), "--out", str(tmp_path / "o.csv")]) == 2
        assert capsys.readouterr().err.splitlines() == [f"vmt import: error: {bad}: {words}"]
    got = subprocess.run([sys.executable, "-c", "from hardware.transcript import read_transcript as r; "
                          "print(r('/dev/stdin')[0].tolist())"], input=body, capture_output=True)
    assert got.returncode == 0 and got.stdout.decode().strip() == "[[1.0, 2.0, 3.0]]", got.stderr.decode()
