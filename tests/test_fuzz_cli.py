"""Fuzz the command line: random corruptions of valid logs and random argument lists.

Every case must end in exit status 0 with its outputs complete, or exit
status 2 with exactly one line on stderr (``vmt CMD: error: ...``) and no
output left behind; never a traceback, never an exception out of
``main()``, never a numpy repr (``np.float64(...)``) in a message.

The cases come from a seeded generator (``FUZZ_SEED``, printed with every
failure so it can be replayed); they run in-process through
``scenarios.cli.main`` with stdout and stderr captured (a process per case
would take minutes), and a few run as real processes for the exit path.
Commands whose valid runs are long (simulate, discover, scenario, demo)
get argument lists with at least one bad value, so they fail in their
checks, before the work.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from core.design import example_cross_pocket
from core.probelog import format_probe_log, make_log, read_probe_log, write_probe_log
from scenarios.cli import main

ROOT = Path(__file__).resolve().parents[1]
FUZZ_SEED = 20260520
N_LOG_CASES = 420          # corrupted logs through `vmt check`
N_IDENTIFY_CASES = 60      # corrupted logs through `vmt identify --json`
N_ARGV_CASES = 160         # random argument lists


# ---------------------------------------------------------------------------
# a small valid campaign, built from geometry alone (no simulator: fast)


def campaign_log(rng, c_deg=(0.0, 75.0, 130.0, 210.0), every=4):
    """A self-calibration campaign: the cross-pocket's targets (every ``every``-th) at
    the C angles, an EC0Y-like squareness and 0.3 um noise along the normal."""
    w, wn, ids = example_cross_pocket()
    w, wn, ids = w[::every], wn[::every], ids[::every]
    cols = {k: [] for k in ("setup", "target", "t_s", "X_mm", "Y_mm", "Z_mm", "Xn_mm", "Yn_mm", "Zn_mm",
                            "nx", "ny", "nz", "feature", "C_deg", "wx_mm", "wy_mm", "wz_mm",
                            "wnx", "wny", "wnz", "status")}
    t = 0.0
    for c in c_deg:
        a = -np.radians(c)
        R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        for p, n, i in zip(w, wn, ids):
            pn, nn = R @ p * 1e3, R @ n
            dq = 20e-6 * pn[1] * nn[0] + rng.normal(0, 0.3e-3)          # mm
            t += rng.uniform(0.5, 2.0)
            for k, v in (("setup", f"C{c:g}"), ("target", i), ("t_s", t), ("X_mm", pn[0] + dq * nn[0]),
                         ("Y_mm", pn[1] + dq * nn[1]), ("Z_mm", -3.0), ("Xn_mm", pn[0]), ("Yn_mm", pn[1]),
                         ("Zn_mm", -3.0), ("nx", nn[0]), ("ny", nn[1]), ("nz", 0.0),
                         ("feature", i.rstrip("0123456789_")), ("C_deg", c), ("wx_mm", p[0] * 1e3),
                         ("wy_mm", p[1] * 1e3), ("wz_mm", -3.0), ("wnx", n[0]), ("wny", n[1]), ("wnz", 0.0),
                         ("status", "ok")):
                cols[k].append(v)
    return make_log(cols, {"machine": "fuzz", "artefact": "cross-pocket", "stylus_r_mm": "3",
                           "kinematic_chain": "V[w-C-A-b-Y-X-Z-(C)-t]"})


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzzbase")
    rng = np.random.default_rng(FUZZ_SEED)
    log = write_probe_log(d / "log.csv", campaign_log(rng))
    plan_log = read_probe_log(log).select(np.arange(read_probe_log(log).n))
    for c in ("X_mm", "Y_mm", "Z_mm", "t_s"):
        plan_log.columns[c][:] = np.nan
    plan = write_probe_log(d / "plan.csv", plan_log)
    n = plan_log.n
    lcnc = d / "probe.txt"
    nom = plan_log.nominals_mm()
    lcnc.write_text("".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in nom.tolist()))
    grbl = d / "session.txt"
    grbl.write_text("".join(f"[PRB:{x:.3f},{y:.3f},{z:.3f}:1]\nok\n" for x, y, z in nom))
    (d / "folder").mkdir()
    (d / "empty.csv").write_text("")
    (d / "binary.csv").write_bytes(bytes(range(256)) * 4)
    (d / "target.json").write_text('{"keep": 1}\n')
    (d / "link.json").symlink_to(d / "target.json")
    return {"dir": d, "log": log, "plan": plan, "n": n, "lcnc": lcnc, "grbl": grbl,
            "text": log.read_text()}


# ---------------------------------------------------------------------------
# running one case


def listing(d: Path) -> list:
    return sorted(str(p.relative_to(d)) for p in d.rglob("*")) if d.exists() else []


def run_case(argv, outdir: Path):
    """Run ``vmt ARGV`` in-process; return (rc, stdout, stderr, problem or None)."""
    before = listing(outdir)
    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                rc = main(argv)
            except SystemExit as e:          # --help, --version
                rc = e.code if isinstance(e.code, int) else 2
    except BaseException as e:                # noqa: BLE001 - anything escaping main() is the bug
        return None, out.getvalue(), err.getvalue(), f"exception out of main(): {type(e).__name__}: {e}"
    o, e = out.getvalue(), err.getvalue()
    if "Traceback" in e:
        return rc, o, e, "traceback on stderr"
    if "np.float64(" in e or "np.float64(" in o or "np.int64(" in e:
        return rc, o, e, "numpy repr in a message"
    if rc == 2:
        lines = e.splitlines()
        if len(lines) != 1 or not re.match(r"vmt( [a-z]+)*: error: \S", lines[0]):
            return rc, o, e, f"exit 2 without exactly one error line ({len(lines)} lines)"
        if listing(outdir) != before:
            return rc, o, e, f"partial output left: {sorted(set(listing(outdir)) - set(before))}"
    elif rc != 0:
        return rc, o, e, f"exit status {rc}"
    return rc, o, e, None


def assert_no_failures(failures, total):
    shown = "\n".join(f"  case {k}: {argv} -> {why}\n    stderr: {err.strip()[:300]!r}"
                      for k, argv, why, err in failures[:8])
    assert not failures, f"{len(failures)} of {total} fuzz cases failed (FUZZ_SEED={FUZZ_SEED}):\n{shown}"


# ---------------------------------------------------------------------------
# corruptions of a valid log

BAD_CELLS = ["", " ", "nan", "NaN", "inf", "-inf", "1e200", "-1e200", "1e308", "1e-320", "0", "-0",
             "abc", "1e", "0x10", "1_000", "+7", "9" * 400, '"1,5"', "é", "--1", ".", "1e5", "-100001",
             "2.5e4", "ok", "o", "no_trigger", "1.0.0", "\t3", "None", "true", "12345678901234567890",
             "-3", "100000", "1e10", "-273.2", "360", "1e6"]
BAD_META = ["# format: probe-log/2", "# stylus_r_mm: -1", "# stylus_r_mm: abc", "# stylus_r_mm: 0",
            "# kinematic_chain: V[w-Q-t]", "# kinematic_chain: ", "#", "# : empty key",
            "# format: probe-log/1", "# stylus_r_mm: 1e300"]
BAD_CHARS = [",", "\n", '"', "\x00", "#", "é", "\r", " ", "-", "e", "9", ".", "\ufeff", "\\"]


def corrupt(text: str, rng) -> tuple[str | bytes, str]:
    """One random corruption of probe-log text; returns (content, what was done)."""
    lines = text.splitlines(keepends=True)
    hdr = next(i for i, x in enumerate(lines) if x.startswith("setup,"))
    kind = int(rng.integers(0, 13))
    if kind == 0:                                          # torn anywhere
        k = int(rng.integers(0, len(text)))
        return text[:k], f"cut at byte {k}"
    if kind == 1:                                          # delete characters
        k = int(rng.integers(0, len(text)))
        m = int(rng.integers(1, 5))
        return text[:k] + text[k + m:], f"delete {m} chars at {k}"
    if kind == 2:                                          # insert a character
        k = int(rng.integers(0, len(text)))
        ch = BAD_CHARS[int(rng.integers(len(BAD_CHARS)))]
        return text[:k] + ch + text[k:], f"insert {ch!r} at {k}"
    if kind == 3:                                          # one cell
        r = int(rng.integers(hdr + 1, len(lines)))
        cells = lines[r].rstrip("\n").split(",")
        j = int(rng.integers(len(cells)))
        v = BAD_CELLS[int(rng.integers(len(BAD_CELLS)))]
        cells[j] = v
        lines[r] = ",".join(cells) + "\n"
        return "".join(lines), f"line {r + 1} cell {j} = {v[:20]!r}"
    if kind == 4:                                          # duplicate or drop or swap lines
        a, b = (int(x) for x in rng.integers(0, len(lines), 2))
        op = int(rng.integers(3))
        if op == 0:
            lines.insert(b, lines[a])
        elif op == 1:
            del lines[a]
        else:
            lines[a], lines[b] = lines[b], lines[a]
        return "".join(lines), f"lines {a + 1},{b + 1} op {op}"
    if kind == 5:                                          # header: rename, drop, duplicate, add
        h = lines[hdr].rstrip("\n").split(",")
        j = int(rng.integers(len(h)))
        op = int(rng.integers(4))
        if op == 0:
            h[j] = ["", "X_mm", "foo", "temp_a_C", "status", " nx"][int(rng.integers(6))]
        elif op == 1:
            del h[j]
        elif op == 2:
            h.append(h[j])
        else:
            h.append(["operator", "temp_spindle_C", "A_deg", "stylus_r_mm"][int(rng.integers(4))])
        lines[hdr] = ",".join(h) + "\n"
        return "".join(lines), f"header op {op} col {j}"
    if kind == 6:                                          # extra column, text or numbers
        vals = [["anna", "bo, b", ""], ["1.5", "", "2"], ["20.5", "nan", "21"], ["x", "1", "-1e300"]]
        name, pool = [("operator", 0), ("gauge_um", 1), ("temp_spindle_C", 2), ("temp_bad_C", 3),
                      ("stylus_r_mm", 1), ("A_deg", 3)][int(rng.integers(6))]
        lines[hdr] = lines[hdr].rstrip("\n") + f",{name}\n"
        for r in range(hdr + 1, len(lines)):
            v = vals[pool][int(rng.integers(3))]
            lines[r] = lines[r].rstrip("\n") + "," + (f'"{v}"' if "," in v else v) + "\n"
        return "".join(lines), f"extra column {name}"
    if kind == 7:                                          # metadata
        m = BAD_META[int(rng.integers(len(BAD_META)))]
        lines.insert(int(rng.integers(0, hdr + 1)), m + "\n")
        return "".join(lines), f"meta {m!r}"
    if kind == 8:                                          # bytes: not UTF-8, BOM, CRLF
        op = int(rng.integers(3))
        if op == 0:
            k = int(rng.integers(0, len(text)))
            b = text.encode()
            return b[:k] + b"\xff\xfe" + b[k:], f"bad bytes at {k}"
        if op == 1:
            return "\ufeff" + text, "BOM"
        return text.replace("\n", "\r\n"), "CRLF"
    if kind == 9:                                          # time: backwards or negative
        r = int(rng.integers(hdr + 1, len(lines)))
        cells = lines[r].rstrip("\n").split(",")
        cells[2] = ["-1", "0", "1e11", "5"][int(rng.integers(4))]
        lines[r] = ",".join(cells) + "\n"
        return "".join(lines), f"t_s line {r + 1} = {cells[2]}"
    if kind == 10:                                         # a normal scaled or a status changed
        r = int(rng.integers(hdr + 1, len(lines)))
        cells = lines[r].rstrip("\n").split(",")
        if rng.random() < 0.5:
            j = int(rng.integers(9, 12))
            cells[j] = repr(float(cells[j]) * [1.001, 1 + 1e-7, -1.0, 1e200, 0.0][int(rng.integers(5))])
        else:
            cells[-1] = ["no_trigger", "alarm", "", "chip"][int(rng.integers(4))]
            if cells[-1] != "ok" and rng.random() < 0.5:
                cells[2:6] = ["", "", "", ""]
        lines[r] = ",".join(cells) + "\n"
        return "".join(lines), f"row line {r + 1} changed"
    if kind == 11:                                         # only a few rows left
        k = int(rng.integers(0, 6))
        return "".join(lines[:hdr + 1 + k]), f"{k} rows"
    # every status invalid, or every measured value empty (a plan)
    for r in range(hdr + 1, len(lines)):
        cells = lines[r].rstrip("\n").split(",")
        cells[3:6] = ["", "", ""]
        if rng.random() < 0.5:
            cells[2] = ""
        lines[r] = ",".join(cells) + "\n"
    return "".join(lines), "measured columns emptied"


def _write(p: Path, content):
    if isinstance(content, bytes):
        p.write_bytes(content)
    else:
        p.write_bytes(content.encode("utf-8"))


def test_fuzz_corrupted_logs_through_check(base, tmp_path):
    rng = np.random.default_rng(FUZZ_SEED + 1)
    failures, codes = [], {0: 0, 2: 0}
    for k in range(N_LOG_CASES):
        content, what = corrupt(base["text"], rng)
        p = tmp_path / "case.csv"
        _write(p, content)
        argv = ["check", str(p)] + (["--json", "-"] if k % 3 == 0 else [])
        rc, o, e, problem = run_case(argv, tmp_path / "out")
        if problem is None and rc == 0 and "--json" in argv:
            try:
                json.loads(o)
            except ValueError:
                problem = "--json printed no valid JSON"
        if problem:
            failures.append((k, f"{argv} [{what}]", problem, e))
        codes[rc] = codes.get(rc, 0) + 1
    assert_no_failures(failures, N_LOG_CASES)
    # the corruptions exercise both outcomes, mostly refusals
    assert codes[2] > N_LOG_CASES / 2 and codes[0] > 10, codes


def test_fuzz_corrupted_logs_through_identify(base, tmp_path):
    rng = np.random.default_rng(FUZZ_SEED + 2)
    failures, codes = [], {}
    out = tmp_path / "out"
    out.mkdir()
    for k in range(N_IDENTIFY_CASES):
        content, what = corrupt(base["text"], rng)
        p = tmp_path / "case.csv"
        _write(p, content)
        res = out / "id.json"
        if res.exists():
            res.unlink()
        argv = ["identify", str(p), "--json", str(res), "--grid-mm", "55"]
        rc, o, e, problem = run_case(argv, out)
        if problem is None and rc == 0:
            try:
                doc = json.loads(res.read_text())
                assert doc["touches"] > 0 and doc["workpiece"]
            except (OSError, ValueError, KeyError, AssertionError) as x:
                problem = f"exit 0 but the JSON is not complete ({x})"
        if problem:
            failures.append((k, f"{argv} [{what}]", problem, e))
        codes[rc] = codes.get(rc, 0) + 1
    assert_no_failures(failures, N_IDENTIFY_CASES)
    assert codes.get(0, 0) > 5 and codes.get(2, 0) > 5, codes


# ---------------------------------------------------------------------------
# random argument lists

NUMBERS = ["0", "-1", "1", "2", "3", "nan", "inf", "-inf", "1e308", "abc", "", "0.5", "90", "120", "-5",
           "1e-9", "360", "7"]


def argv_case(rng, b, out: Path) -> list:
    """One random argument list for a command whose valid runs are short, or with a bad value."""
    d = b["dir"]
    pick = lambda pool: pool[int(rng.integers(len(pool)))]          # noqa: E731
    inputs = [str(b["log"]), str(b["log"]), str(d / "missing.csv"), str(d / "folder"), "/dev/null",
              str(d / "empty.csv"), str(d / "binary.csv"), str(b["plan"])]
    outputs = [str(out / "r.json"), str(out / "r.json"), str(out / "sub" / "deep" / "r.json"),
               str(d / "folder"), "/dev/full", str(d / "link.json"), str(b["log"]) + "/x.json",
               str(b["log"]), str(out / "r.csv")]
    cmd = int(rng.integers(0, 11))
    if cmd == 0:
        return ["check", pick(inputs)] + (["--json", "-"] if rng.random() < 0.3 else [])
    if cmd == 9:        # plan grid: small grids only
        a = ["plan", "grid", "--x-mm", pick(["0:30:10", "0:30:0", "30:0:10", "a:b:c", "0:1e9:1", "nan:1:1"]),
             "--y-mm", pick(["0:20:10", "0:20:-1", ""]), "--out", pick(outputs)]
        if rng.random() < 0.4:
            a += ["--stylus-r-mm", pick(["0", "1.5", "-1", "nan", "1e9"])]
        if rng.random() < 0.3:
            a += ["--z-mm", pick(NUMBERS)]
        return a
    if cmd == 10:
        a = ["fit", pick(["plane", "sphere", "circle", "cylinder", "cone"]), pick(inputs)]
        if rng.random() < 0.5:
            a += ["--json", pick(outputs)]
        if rng.random() < 0.4:
            a += ["--stylus-r-mm", pick(["0", "1.5", "-1", "nan", "1e9"])]
        return a
    if cmd == 1:
        a = ["identify", pick(inputs), "--json", pick(outputs), "--grid-mm", "55"]
        for opt, pool in (("--grid-mm", ["55", "55", "22", "0", "-5", "nan", "abc", "-110:110:55", "1:1:1", "1e9"]),
                          ("--mc", ["0", "10", "-1", "3", "x"]), ("--seed", ["0", "-1", "7", "1.5"]),
                          ("--noise-um", NUMBERS), ("--delta-l-um", NUMBERS)):
            if rng.random() < 0.35:
                a += [opt, pick(pool)]
        return a
    if cmd in (2, 3):
        kind = "linuxcnc" if cmd == 2 else "grbl"
        f = str(b["lcnc"] if cmd == 2 else b["grbl"])
        a = ["import", kind, pick([f, f, str(d / "folder"), str(d / "missing.txt"), str(b["log"])]),
             "--plan", pick([str(b["plan"]), str(b["plan"]), str(b["log"]), str(d / "folder")]),
             "--out", pick(outputs + [str(b["plan"])])]
        if rng.random() < 0.5:
            a += ["--dt-s", pick(NUMBERS)]
        if cmd == 2 and rng.random() < 0.3:
            a += ["--units", pick(["mm", "inch", "m"])]
        return a
    if cmd == 4:        # design: small searches only (step >= 90 deg, <= 3 angles)
        a = ["design", "--plan", pick([str(b["plan"]), str(b["log"]), str(d / "folder"), str(d / "missing.csv")]),
             "--n-angles", pick(["2", "3", "0", "1", "-1", "2.5", "x", "1000"]),
             "--step-deg", pick(["90", "120", "180", "0", "-5", "nan", "inf", "7", "abc", "1e-9", "400"]),
             "--workers", "1"]
        if rng.random() < 0.4:
            a += ["--grid-mm", pick(["-110:110:44", "0", "abc", "1:1:1", "-110:110:0", "nan:1:1", "5"])]
        if rng.random() < 0.4:
            a += ["--reference-deg", pick(["0,90,180", "", "a,b", "nan", "0,75,130,210"])]
        if rng.random() < 0.4:
            a += ["--noise-um", pick(NUMBERS)]
        if rng.random() < 0.5:
            a += ["--json", pick(outputs)]
        return a
    # long commands: at least one bad value, so they must stop in their checks
    bad_out = pick([str(d / "folder"), str(b["log"]) + "/x", str(d / "link.json")])
    if cmd == 5:
        a = ["simulate", pick(["cross-pocket", "mfb", "pin-circle", "freeform"]), "--out", str(out / "s.csv")]
        for opt, val in (("--noise-um", pick(["-1", "nan", "inf"])), ("--seed", "-3"),
                         ("--machine", "nonesuch"), ("--c-angles-deg", pick(["a,b", "nan", "0,0", "1e400"])),
                         ("--out", bad_out)):
            if rng.random() < 0.5:
                a += [opt, val]
        if a[-2:] == ["--out", str(out / "s.csv")] and len(a) == 4:
            a += ["--seed", "-3"]
        return a
    if cmd == 6:
        a = ["discover", pick([str(d / "missing.csv"), str(d / "folder"), str(d / "empty.csv"), "/dev/null",
                               str(b["plan"]), str(b["log"])]), "--json", pick(outputs)]
        if a[1] == str(b["log"]):
            a[3] = pick([bad_out, str(b["log"])])      # the input itself is a bad output too
        if rng.random() < 0.5:
            a += ["--report", pick([str(out / "rep"), str(b["log"]), str(d / "folder")])]
        return a
    if cmd == 7:
        a = ["scenario", pick(["mfb-3axis", "mfb-5axis", "cross-pocket-uncertainty", "pin-circle", "nonesuch"])]
        for opt, val in (("--seed", "-1"), ("--mc", pick(["-1", "x"])), ("--noise-um", pick(["-1", "nan"])),
                         ("--json", bad_out)):
            if rng.random() < 0.5:
                a += [opt, val]
        if len(a) == 2:
            a += ["--seed", "-1"]
        return a
    return ["demo", "--out-dir", pick([str(b["log"]), str(b["log"]) + "/x"]), "--seed", pick(["1", "-1"])] + \
        pick([[], ["--bogus"], ["--seed"]])


def test_fuzz_argument_lists(base, tmp_path):
    rng = np.random.default_rng(FUZZ_SEED + 3)
    failures, codes = [], {}
    plan_before, log_before = base["plan"].read_bytes(), base["log"].read_bytes()
    for k in range(N_ARGV_CASES):
        out = tmp_path / f"o{k}"
        out.mkdir()
        argv = argv_case(rng, base, out)
        rc, o, e, problem = run_case(argv, out)
        if problem is None and rc == 0:
            written = [p for p in out.rglob("*") if p.is_file()]
            for p in written:
                try:
                    text = p.read_text()
                    json.loads(text) if text.startswith("{") else read_probe_log(p)
                except Exception as x:  # noqa: BLE001
                    problem = f"exit 0 but {p.name} is not complete ({x})"
        if problem is None and (base["plan"].read_bytes() != plan_before
                                or base["log"].read_bytes() != log_before):
            problem = "an input was changed"
            base["plan"].write_bytes(plan_before)
            base["log"].write_bytes(log_before)
        if problem:
            failures.append((k, argv, problem, e))
        codes[rc] = codes.get(rc, 0) + 1
    assert_no_failures(failures, N_ARGV_CASES)
    assert codes.get(0, 0) > 5 and codes.get(2, 0) > N_ARGV_CASES / 2, codes
    assert (base["dir"] / "link.json").is_symlink() and json.loads((base["dir"] / "target.json").read_text()) == {"keep": 1}


# ---------------------------------------------------------------------------
# the real exit path: a few cases as processes


def _vmt(*argv, **kw):
    return subprocess.run([sys.executable, "-m", "scenarios.cli", *argv], cwd=ROOT, capture_output=True,
                          text=True, timeout=120, **kw)


def test_real_process_exit_status_and_one_line(base, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text(base["text"].replace("\nC0,", "\nC0,,", 1))
    for argv in (["check", str(bad)],
                 ["identify", str(base["log"]), "--json", "/dev/full"],
                 ["import", "linuxcnc", str(base["lcnc"]), "--plan", str(base["plan"]), "--out", str(base["plan"])],
                 ["design", "--plan", str(base["plan"]), "--n-angles", "3", "--step-deg", "0"]):
        r = _vmt(*argv)
        assert r.returncode == 2, (argv, r.stderr)
        assert r.stderr.count("\n") == 1 and r.stderr.startswith(f"vmt {argv[0]}: error: "), (argv, r.stderr)
    # a folder given as the log: `check` has its real process above, so this one runs in-process
    rc, _, e, problem = run_case(["check", str(base["dir"] / "folder")], tmp_path)
    assert (rc, problem) == (2, None) and e.startswith("vmt check: error: "), e


def test_real_process_closed_pipe_ends_quietly(tmp_path):
    """`vmt import ... --out /dev/stdout | head -c 100`: 150 kB into a pipe whose reader leaves after
    100 bytes: no BrokenPipe traceback, no message, status 141 (as if killed by SIGPIPE)."""
    log = campaign_log(np.random.default_rng(1), c_deg=tuple(30.0 * np.arange(12)), every=1)
    plan = log.select(np.arange(log.n))
    for c in ("X_mm", "Y_mm", "Z_mm", "t_s"):
        plan.columns[c][:] = np.nan
    write_probe_log(tmp_path / "plan.csv", plan)
    (tmp_path / "probe.txt").write_text("".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in plan.nominals_mm().tolist()))
    r = subprocess.run(f"{sys.executable} -m scenarios.cli import linuxcnc probe.txt --plan plan.csv "
                       f"--out /dev/stdout | head -c 100 > /dev/null; echo \"${{PIPESTATUS[0]}}\"",
                       shell=True, executable="/bin/bash", cwd=tmp_path, capture_output=True, text=True,
                       timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.stderr == "", r.stderr
    assert r.stdout.strip() == "141", r.stdout
    assert len(format_probe_log(plan)) > 2 * 65536              # more than a pipe holds
