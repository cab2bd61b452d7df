"""`vmt machine program` writes only the controller's axes (review32a F1).

LinuxCNC's interpreter refuses an axis letter its machine lacks (rs274ngc_pre.cc drops the word
reader of every axis outside the axis mask: "Bad character 'b' used"; the reviewer confirmed it on
LinuxCNC 2.9 with an XYZAC config). Before session 32 the program wrote A, B and C words for any plan
with rotary columns: the README's nmv3000 cross-pocket plan stopped at its ``G10 L2 P9 X0 Y0 Z0 A0 B0 C0
R0``, and a vmc-3axis plan (rotary columns, all zero) wrote ``A0 B0 C0`` for a 3-axis controller. The
axes now come from ``--axes`` (the name and meaning of ``vmt probe --axes``), ``--machine``, or the
machine the plan names; a row that turns an axis the controller lacks is refused in one line.
"""

import re

import numpy as np
import pytest

from conftest import LIMITS, plan_log
from core.exceptions import PlanError
from core.probelog import make_log, read_probe_log, write_probe_log
from hardware.campaign import ProbeSettings
from hardware.linuxcnc import part_program
from scenarios.cli import main

#: README's `vmt machine program` line for the cross-pocket plan (limits, safe Z), verbatim
README_ARGS = ["--probe-file", "probe.txt", "--limits-mm", "X-250:250,Y-250:250,Z-100:200", "--safe-z-mm", "80"]
#: an axis word in G-code outside comments: a letter then a number (not '#<_vmt_wcs_b>', not 'DEBUG')
AXIS_WORD = re.compile(r"(?<![A-Za-z_#<])([ABCXYZ])(-?\d+(?:\.\d*)?)(?![A-Za-z_])")


def code_words(text):
    """Every (letter, value) of the program's G-code, comments removed."""
    out = []
    for ln in text.splitlines():
        code = re.sub(r"\([^)]*\)", "", ln)
        out += AXIS_WORD.findall(code)
    return out


@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    d = tmp_path_factory.mktemp("plans")
    for name, machine in (("plan5.csv", "nmv3000"), ("plan3.csv", "vmc-3axis")):
        assert main(["simulate", "cross-pocket", "--plan-only", "--machine", machine, "--out", str(d / name)]) == 0
    return d


def program(plans, plan, *extra):
    out = plans / "p.ngc"
    if out.exists():
        out.unlink()
    rc = main(["machine", "program", "--plan", str(plans / plan), "--out", str(out), *README_ARGS, *extra])
    return rc, (out.read_text() if rc == 0 else None)


def test_readme_program_writes_the_nmv3000s_axes_only(plans, capsys):
    """The README's program (nmv3000, XYZAC): no B word anywhere, the frame zeroed with A and C, every turn
    carries A and C; the axes come from the plan's kinematic_chain and the output line says so."""
    rc, text = program(plans, "plan5.csv")
    assert rc == 0
    letters = {a for a, _ in code_words(text)}
    assert letters == set("XYZAC")
    assert "axes XYZAC (the plan's kinematic_chain)" in capsys.readouterr().out
    assert "G10 L2 P9 X0 Y0 Z0 A0 C0 R0" in text.splitlines()
    assert "A#<_vmt_wcs_a> C#<_vmt_wcs_c> R#<_vmt_wcs_r>" in text and "_vmt_wcs_b" not in text
    turns = [ln for ln in text.splitlines() if ln.startswith("G1 ") and re.search(r" [AC]-?\d", ln)]
    assert len(turns) == 4 and all(" A" in t and " C" in t for t in turns)     # one per set-up: C 0, 75, 130, 210
    assert [float(re.search(r" C(-?\d+\.\d+)", t)[1]) for t in turns] == [0.0, 75.0, 130.0, 210.0]


def test_xyz_plan_writes_no_rotary_word(plans, capsys):
    """The vmc-3axis plan (rotary columns, all zero): no A, B or C word, the frame zeroed X Y Z R only."""
    rc, text = program(plans, "plan3.csv")
    assert rc == 0
    assert {a for a, _ in code_words(text)} == set("XYZ")
    assert "axes XYZ (the plan's kinematic_chain)" in capsys.readouterr().out
    assert "G10 L2 P9 X0 Y0 Z0 R0" in text.splitlines()


def test_axes_option_and_machine(plans, capsys):
    """--axes (vmt probe's name and meaning) overrides the plan; --machine gives its chain's axes; a 6-axis
    controller gets all three rotary words."""
    rc, text = program(plans, "plan5.csv", "--axes", "xyzabc")
    assert rc == 0 and "axes XYZABC (--axes)" in capsys.readouterr().out
    assert {a for a, _ in code_words(text)} == set("XYZABC")
    assert "G10 L2 P9 X0 Y0 Z0 A0 B0 C0 R0" in text.splitlines()
    # --machine: its axes (and its strokes as the limits)
    out = plans / "m.ngc"
    assert main(["machine", "program", "--plan", str(plans / "plan5.csv"), "--out", str(out), "--safe-z-mm", "80",
                 "--machine", "nmv3000"]) == 0
    assert "axes XYZAC (machine nmv3000)" in capsys.readouterr().out
    assert {a for a, _ in code_words(out.read_text())} == set("XYZAC")


@pytest.mark.parametrize("extra, msg", [
    (["--axes", "XYZA"], r"row 92 \(target 'wall00_0'\) turns C to 75 deg but the controller's axes are XYZA: "
                         r"no C axis to turn"),
    (["--axes", "XYZ"], r"row 92 \(target 'wall00_0'\) turns C to 75 deg but the controller's axes are XYZ"),
    (["--axes", "XYZQ"], r"--axes 'XYZQ': expected X, Y, Z then rotary axes A, B, C \(e\.g\. XYZAC\)"),
    (["--axes", "XZY"], r"--axes 'XZY': expected X, Y, Z then"),
    (["--axes", "XYZAA"], r"--axes 'XYZAA': expected"),
])
def test_an_axis_the_controller_lacks_is_refused(plans, capsys, extra, msg):
    """A plan that turns C on a controller without C, or a bad --axes: one line, exit 2, nothing written."""
    capsys.readouterr()
    rc, _ = program(plans, "plan5.csv", *extra)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert re.search(msg, err), err
    assert not (plans / "p.ngc").exists()


def test_plan_naming_a_machine_without_a_chain(plans, tmp_path, capsys):
    """A plan that names a built-in machine but carries no kinematic_chain (made by hand, or by an older vmt):
    the machine's axes; a rotary plan naming nothing is refused in one line."""
    plan = read_probe_log(plans / "plan5.csv")
    meta = {k: v for k, v in plan.meta.items() if k != "kinematic_chain"}
    p = tmp_path / "named.csv"
    write_probe_log(p, make_log(dict(plan.columns), meta))
    capsys.readouterr()
    out = tmp_path / "n.ngc"
    assert main(["machine", "program", "--plan", str(p), "--out", str(out), *README_ARGS]) == 0
    assert "axes XYZAC (the plan's machine nmv3000)" in capsys.readouterr().out
    assert {a for a, _ in code_words(out.read_text())} == set("XYZAC")
    meta.pop("machine")
    write_probe_log(p, make_log(dict(plan.columns), meta))
    assert main(["machine", "program", "--plan", str(p), "--out", str(out), *README_ARGS]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "rotary columns (A_deg, B_deg, C_deg) but names no machine" in err


def test_machine_without_the_axis_is_refused(plans, capsys):
    """--machine vmc-3axis (no rotary axis) under the nmv3000 plan: its C turns are refused by row."""
    capsys.readouterr()
    assert main(["machine", "program", "--plan", str(plans / "plan5.csv"), "--out", str(plans / "v.ngc"),
                 "--safe-z-mm", "80", "--machine", "vmc-3axis", "--limits-mm", LIMITS]) == 2   # one of the two
    assert "--machine and --limits-mm" in capsys.readouterr().err
    assert main(["machine", "program", "--plan", str(plans / "plan5.csv"), "--out", str(plans / "v.ngc"),
                 "--safe-z-mm", "80", "--machine", "vmc-3axis"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "turns C to 75 deg but the controller's axes are XYZ" in err
    assert not (plans / "v.ngc").exists()


def _with_rotary(plan, a=None, b=None, c=None, meta=None):
    cols = dict(plan.columns)
    for name, v in (("A_deg", a), ("B_deg", b), ("C_deg", c)):
        cols[name] = np.full(plan.n, 0.0) if v is None else np.asarray(v, float)
    return make_log(cols, dict(plan.meta if meta is None else meta))


def test_library_rules():
    """program_axes: --axes first, then the plan's chain, XYZ without rotary columns;
    a rotary plan of no known machine is refused (no guess: writing A B C was the bug, writing none would leave
    a real table where it stands). A non-zero B on an XYZAC controller is refused naming row and angle; a B
    column of zeros is not a turn and writes no B."""
    from hardware.linuxcnc import program_axes

    s = ProbeSettings(limits_mm=((-300, 300),) * 3, safe_z_mm=30.0)
    flat = plan_log()
    assert program_axes(flat) == ("XYZ", "the plan has no rotary columns")
    chained = _with_rotary(flat, meta={**flat.meta, "kinematic_chain": "V[w-C-A-b-Y-X-Z-(C)-t]"})
    assert program_axes(chained) == ("XYZAC", "the plan's kinematic_chain")
    assert program_axes(chained, "XYZB") == ("XYZB", "--axes")
    bare = _with_rotary(flat)
    with pytest.raises(PlanError, match=r"rotary columns .* names no machine: .*--axes \(e\.g\. XYZAC\)"):
        part_program(bare, s)
    text = part_program(bare, s, axes="XYZAC")                  # B all zero: not a turn, no B word
    assert {a for a, _ in code_words(text)} == set("XYZAC")
    b = np.zeros(flat.n)
    b[5] = 15.0
    with pytest.raises(PlanError, match=r"^row 5 \(target 's1'\) turns B to 15 deg but the controller's axes are "
                                        r"XYZAC: no B axis to turn"):
        part_program(_with_rotary(flat, b=b), s, axes="XYZAC")
    assert "B15.0000" in part_program(_with_rotary(flat, b=b), s, axes="XYZB")
    # a plan without rotary columns on a 5-axis controller: no rotary word (the program turns nothing)
    assert {a for a, _ in code_words(part_program(flat, s, axes="XYZAC"))} == set("XYZ")


def test_program_imports_back(plans, tmp_path):
    """The XYZAC program's LOG lines, as LinuxCNC would write them at the nominal touch points, import against the
    plan (the axes change no row numbering or stroke)."""
    rc, text = program(plans, "plan5.csv")
    assert rc == 0
    plan = read_probe_log(plans / "plan5.csv")
    xyz = np.column_stack([plan.col(c) for c in ("Xn_mm", "Yn_mm", "Zn_mm")])
    logs = [ln for ln in text.splitlines() if ln.startswith("(LOG,N")]
    assert len(logs) == plan.n
    lines = []
    for ln, p in zip(logs, xyz):
        body = ln[5:-1].replace("X#5061 Y#5062 Z#5063", f"X{p[0]:.6f} Y{p[1]:.6f} Z{p[2]:.6f}")
        lines.append(body)
    f = tmp_path / "probe.txt"
    f.write_text("\n".join(lines) + "\n")
    out = tmp_path / "cnc.csv"
    assert main(["import", "linuxcnc", str(f), "--plan", str(plans / "plan5.csv"), "--out", str(out)]) == 0
    assert read_probe_log(out).ok.all()


# --------------------------------------------------------------------------- a run continued (review32a F3)
def _as_linuxcnc_writes(text, xyz):
    """The probe file LinuxCNC writes running ``text`` with every probe touching at ``xyz[row]``: each LOG line
    with #5061-#5063 expanded (6 decimals, as LinuxCNC's %f)."""
    out = []
    for ln in text.splitlines():
        m = re.match(r"\(LOG,N(\d+) (.*)\)$", ln)
        if m:
            p = xyz[int(m[1])]
            out.append(f"N{m[1]} " + m[2].replace("X#5061 Y#5062 Z#5063", f"X{p[0]:.6f} Y{p[1]:.6f} Z{p[2]:.6f}"))
    return out


def test_from_row_appends_and_imports_as_one_run(plans, tmp_path, capsys):
    """A run that stopped at row K, continued with --from-row K: the second program opens the file with LOGAPPEND
    (LinuxCNC: fopen "at", emccanon.cc), starts at row K (Z alone to the safe Z, then the set-up's turn), and the
    two runs' lines import as one file, every touch on its row, equal to a run of the whole plan. The default
    program opens with LOGOPEN (fopen "wt": it empties the file) and says so in its header."""
    plan = read_probe_log(plans / "plan5.csv")
    rng = np.random.default_rng(5)
    xyz = np.column_stack([plan.col(c) for c in ("Xn_mm", "Yn_mm", "Zn_mm")])
    d = np.column_stack([plan.col(c) for c in ("dx", "dy", "dz")])
    xyz = xyz + d * rng.uniform(-0.05, 0.05, (plan.n, 1))        # touches along each row's line, +-50 um
    rc, whole = program(plans, "plan5.csv")
    assert rc == 0 and "LOGOPEN empties it" in capsys.readouterr().out
    assert "(LOGOPEN,probe.txt)" in whole and "(LOGOPEN truncates probe.txt: after a stop, copy or import" in whole
    k = 150                                                         # in set-up C75 (rows 92..183)
    first = _as_linuxcnc_writes(whole, xyz)[:k]                      # the run stopped at row k (a miss)
    rc, rest = program(plans, "plan5.csv", "--from-row", str(k))
    out = capsys.readouterr().out
    assert rc == 0 and f"rows {k}..{plan.n - 1} ({plan.n - k} of {plan.n} touches)" in out and "LOGAPPEND" in out
    lines = rest.splitlines()
    assert "(LOGAPPEND,probe.txt)" in lines and "(LOGOPEN,probe.txt)" not in lines
    assert f"(LOGAPPEND: probe.txt must hold that run's lines N0..N{k - 1}; these rows follow them)" in lines
    logs = [ln for ln in lines if ln.startswith("(LOG,N")]
    assert len(logs) == plan.n - k and logs[0].startswith(f"(LOG,N{k} ") and logs[-1].startswith(f"(LOG,N{plan.n - 1} ")
    moves = [ln for ln in lines if ln.startswith("G1 ")]
    assert moves[0] == "G1 Z80.000000 F1000.0"                      # Z alone first: X, Y unknown after a stop
    assert moves[1] == "G1 Z80.000000 A0.0000 C75.0000 F1000.0"     # then the row's set-up angles, alone
    # the second run's rows, as LinuxCNC appends them
    second = _as_linuxcnc_writes(rest, xyz)
    f = tmp_path / "probe.txt"
    f.write_text("\n".join(first + second) + "\n")
    one = tmp_path / "one.txt"
    one.write_text("\n".join(_as_linuxcnc_writes(whole, xyz)) + "\n")
    assert f.read_text() == one.read_text()                         # the same lines as one whole run
    out = tmp_path / "cnc.csv"
    assert main(["import", "linuxcnc", str(f), "--plan", str(plans / "plan5.csv"), "--out", str(out)]) == 0
    log = read_probe_log(out)
    assert log.ok.all() and np.abs(log.positions_mm() - xyz).max() < 6e-7    # the file's 6 decimals: 0.5 nm
    # the wrong K (a row skipped, or repeated) leaves a gap the import refuses, naming the line
    rc, skip = program(plans, "plan5.csv", "--from-row", str(k + 1))
    f.write_text("\n".join(first + _as_linuxcnc_writes(skip, xyz)) + "\n")
    capsys.readouterr()
    assert main(["import", "linuxcnc", str(f), "--plan", str(plans / "plan5.csv"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"line {k + 1}: N{k + 1}, but it is probe line {k + 1}, plan row {k}'s" in err


@pytest.mark.parametrize("k", ["-1", "368", "1.5", "x"])
def test_bad_from_row_is_refused(plans, capsys, k):
    capsys.readouterr()
    try:
        rc, _ = program(plans, "plan5.csv", "--from-row", k)
    except SystemExit as e:          # argparse's own refusal of a non-integer (one line, status 2)
        rc = e.code
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "--from-row" in err and "Traceback" not in err, err
    assert not (plans / "p.ngc").exists()


def test_a_stopped_import_names_the_row_to_continue_from(plans, tmp_path, capsys):
    """`vmt import linuxcnc` of a stopped run's numbered file says the --from-row that continues it."""
    plan = read_probe_log(plans / "plan5.csv")
    xyz = np.column_stack([plan.col(c) for c in ("Xn_mm", "Yn_mm", "Zn_mm")])
    rc, whole = program(plans, "plan5.csv")
    f = tmp_path / "probe.txt"
    f.write_text("\n".join(_as_linuxcnc_writes(whole, xyz)[:3]) + "\n")
    capsys.readouterr()
    assert main(["import", "linuxcnc", str(f), "--plan", str(plans / "plan5.csv"),
                 "--out", str(tmp_path / "l.csv")]) == 0
    assert "to continue: vmt machine program --from-row 3 (appends to this file: keep it)" in capsys.readouterr().out


def test_header_says_which_way_a_positive_angle_turns(plans):
    """review33b F3: the program's header says that +C turns the part by minus the angle (a table clockwise seen
    from +Z, ISO 841) and suggests the dry check, and the plan it runs is so: the same target at C = 75 deg lies
    at R(-75 deg) of its C = 0 position about the C line (nmv3000: through the origin), checked on the plan's
    nominal points (tolerance 1e-9 mm: the plan prints shortest round-trip floats). An XYZ program has no such
    lines (no rotary axis)."""
    rc, text = program(plans, "plan5.csv")
    assert rc == 0
    head = text.split("\nM70\n")[0]
    assert "(rotary axes A C: a positive angle is a right-handed turn of the tool relative to the part [ISO 841]:)" \
        in head.splitlines()
    assert "clockwise seen from the + end of X, Y, Z" in head and "turn C by +90" in head
    assert "must turn clockwise seen from +Z, from above" in head
    assert all(len(ln) <= 120 and ln.count("(") == 1 for ln in head.splitlines() if "rotary" in ln or "turn" in ln)
    log = read_probe_log(plans / "plan5.csv")
    tgt, setup = log.col("target"), log.col("setup")
    p = np.column_stack([log.col("Xn_mm"), log.col("Yn_mm")])
    c = np.radians(75.0)
    turn = np.array([[np.cos(-c), -np.sin(-c)], [np.sin(-c), np.cos(-c)]])    # R(-C)
    at0 = {t: p[i] for i, t in enumerate(tgt) if setup[i] == "C0"}
    pairs = [(at0[t], p[i]) for i, t in enumerate(tgt) if setup[i] == "C75" and t in at0]
    assert len(pairs) > 50
    for p0, p75 in pairs:
        np.testing.assert_allclose(p75, turn @ p0, atol=1e-9)
    rc, text = program(plans, "plan3.csv")
    assert rc == 0 and "rotary axes" not in text and "turn C by" not in text
