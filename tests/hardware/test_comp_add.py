"""A compensation table measured with a table loaded is a residual: `--add-to` adds it (review32a F2).

LinuxCNC keeps one table per joint, built from the COMP_FILE (usrmotLoadComp), and ignores BACKLASH with it:
a file of a residual loaded in the old one's place undoes the old correction (review32a, the Mikron's X:
24 um -> 0.66 um -> about 24 um). :func:`hardware.linuxcnc.add_comp` writes the old table plus the residual,
each as LinuxCNC interpolates it (linear between lines, ends held), on the union of their lines.
"""

import numpy as np
import pytest

from core.exceptions import ConfigError
from core.positioning import arrange
from core.units import MM
from hardware.linuxcnc import COMP_SIZE, add_comp, comp_text, positioning_comp_file, read_comp_file
from scenarios.cli import main
from sim.compensation import AxisCompensation, JointTable
from sim.machine import Machine
from sim.machinefile import truth_machine
from sim.positioning import positioning_plan, simulate_positioning


def test_known_answer():
    """Hand-made tables, mm: the sum on the union of the lines, the residual held beyond its one line."""
    old = np.array([[0.0, 0.010, 0.012], [10.0, 10.020, 10.020]])
    res = np.array([[5.0, 5.001, 4.999]])
    got = add_comp(old, res)
    want = np.array([[0.0, 0.011, 0.011],            # old 0.010 / 0.012, residual held +0.001 / -0.001
                     [5.0, 5.016, 5.015],            # old interpolated 0.015 / 0.016
                     [10.0, 10.021, 10.019]])
    assert np.allclose(got, want, rtol=0, atol=1e-12)   # sums of a few doubles: 1e-12 mm is rounding only
    assert comp_text(got).splitlines()[1] == "5.000000 5.016000 5.015000"


def test_sum_is_what_linuxcnc_would_apply_for_both():
    """Everywhere (between lines, beyond either table's ends), the summed table's trim equals the old trim plus
    the residual's, as sim.compensation.JointTable applies a file (compute_screw_comp)."""
    rng = np.random.default_rng(3)
    x_old = np.sort(np.round(rng.uniform(-300, 300, 40), 6))      # 6 decimals, as every file's nominals
    old = np.column_stack([x_old, x_old + rng.normal(0, 0.02, 40), x_old + rng.normal(0, 0.02, 40)])
    x_res = np.sort(np.round(rng.uniform(-250, 280, 11), 6))
    res = np.column_stack([x_res, x_res + rng.normal(0, 0.001, 11), x_res + rng.normal(0, 0.001, 11)])
    tab = lambda r: JointTable.from_type0(np.asarray(r) * MM)     # noqa: E731
    both = tab(add_comp(old, res))
    q = np.linspace(-400, 400, 4001) * MM
    for d in (1, -1):
        want = tab(old).trim(q, d) + tab(res).trim(q, d)
        # the union of 6-decimal nominals is exact; what is left is the rounding of sums of doubles of a few
        # hundred mm (1e-13 mm): 1e-15 m
        assert np.abs(both.trim(q, d) - want).max() < 1e-15


@pytest.mark.parametrize("old, res, msg", [
    (np.array([[0.0, 0, 0], [0.0, 1, 1]]), np.array([[1.0, 1, 1]]), "the old table must be"),
    (np.array([[0.0, 0, 0]]), np.array([[1.0, np.nan, 1]]), "the residual table must be"),
    (np.array([0.0, 0, 0]), np.array([[1.0, 1, 1]]), "the old table must be"),
    (np.column_stack([np.arange(200.0)] * 3), np.column_stack([np.arange(200.0) + 0.5] * 3), "400 lines in the union"),
])
def test_bad_tables_are_refused(old, res, msg):
    with pytest.raises(ConfigError, match=msg):
        add_comp(old, res)
    assert COMP_SIZE == 256


def _rows(text):
    return np.array([[float(v) for v in ln.split()] for ln in text.splitlines()])


@pytest.mark.parametrize("name, axis", [("vmc-3axis", "X"), ("vmc-3axis", "Z"), ("mikron-ucp710", "X")])
def test_closed_loop(name, axis):
    """truth -> test -> file -> the machine with it loaded -> test again (its residual) -> next file. The
    residual's file alone gives the uncompensated machine back (the finding); the sum takes it further
    down. Noise-free exact simulator, the same targets each time; figure: the range of the mean deviations
    at the targets (both directions), um. Measured (session 32): vmc X 54.232 / 0.0308 / 54.218 / 0.0009,
    vmc Z 14.666 / 0.0014 / 14.666 / 0.0008, Mikron X 51.958 / 0.0207 / 51.979 / 0.0007."""
    m = Machine(truth_machine(name).config)
    plan = positioning_plan(m, axis, rng=np.random.default_rng(0))

    def test(machine):
        t = arrange(simulate_positioning(machine, plan, np.random.default_rng(1)))
        return t, np.ptp(np.r_[np.nanmean(t.dev_up, 1), np.nanmean(t.dev_down, 1)]) * 1e3     # mm -> um

    def loaded(rows):
        return AxisCompensation(m, {axis: JointTable.from_type0(rows * MM)})

    t0, none = test(m)
    first = _rows(positioning_comp_file(t0))
    t1, after1 = test(loaded(first))
    residual = _rows(positioning_comp_file(t1))
    _, alone = test(loaded(residual))
    _, summed = test(loaded(add_comp(first, residual)))
    assert none > 10.0
    # the first file leaves the second-order term (E taken at x + trim, not x: slope ~1e-4 x trims of tens of
    # um, a few nm, plus the file's 6 decimals): under 0.1 um
    assert after1 < 0.1
    assert alone == pytest.approx(none, rel=0.01)            # the residual alone undoes the first file
    # the sum removes that term too, to the file's rounding (0.5 nm per value): 10x below the first file's
    assert summed < 0.1 * after1 or summed < 0.002


def test_cli(tmp_path, capsys):
    """iso230-2 --comp-file NEW --add-to OLD: NEW = add_comp(OLD, the residual's table); it says so; without
    --add-to it says the file replaces BACKLASH and an earlier table. Bad uses: one line, exit 2."""
    log = tmp_path / "x.csv"
    assert main(["simulate", "positioning", "--machine", "vmc-3axis", "--axis", "X", "--out", str(log)]) == 0
    capsys.readouterr()
    res, old, new = tmp_path / "res.comp", tmp_path / "old.comp", tmp_path / "new.comp"
    assert main(["iso230-2", str(log), "--json", str(tmp_path / "a.json"), "--comp-file", str(res)]) == 0
    assert (f"note: {res} replaces the joint's BACKLASH and any earlier COMP_FILE in LinuxCNC"
            in capsys.readouterr().out)
    old.write_text("-400.000000 -399.990000 -399.980000\n0.000000 0.005000 0.004000\n400.000000 400.010000 "
                   "400.020000\n")
    assert main(["iso230-2", str(log), "--json", str(tmp_path / "b.json"), "--comp-file", str(new),
                 "--add-to", str(old)]) == 0
    assert f"note: {new} is {old} plus this test's residual: load it in {old}'s place" in capsys.readouterr().out
    assert new.read_text() == comp_text(add_comp(read_comp_file(old), read_comp_file(res)))
    for extra, msg in ((["--add-to", str(old)], "--add-to: give --comp-file too"),
                       (["--comp-file", str(old), "--add-to", str(old)], "refusing to overwrite an input"),
                       (["--comp-file", str(new), "--add-to", str(tmp_path / "none.comp")], "no such file"),
                       (["--comp-file", str(new), "--add-to", str(log)], "is not a number")):
        assert main(["iso230-2", str(log), "--json", str(tmp_path / "c.json"), *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and msg in err and "Traceback" not in err, err
        assert not (tmp_path / "c.json").exists()


def _rotary_log(targets_deg, dev_up, dev_down, unit="deg"):
    """Two cycles of a positioning test, the same mean deviations each cycle (file unit)."""
    from core.positioning import make_positioning_log

    tg, cy, di, me = [], [], [], []
    for c in (1, 2):
        for d, dev in (("+", dev_up), ("-", dev_down)):
            for t, e in zip(targets_deg, dev):
                tg.append(t), cy.append(c), di.append(d), me.append(t + e)
    return make_positioning_log(tg, cy, di, me, unit=unit, meta={"axis": "C" if unit == "deg" else "X"})


def test_rotary_file_closes_the_turn():
    """review33b F6 (its cpos.csv): C tested at 0, 90, 180, 270 deg. LinuxCNC looks the table up at the joint
    command with no modulo (compute_screw_comp: linear between lines, end lines held; sim JointTable), so the
    file of the four targets left 270-360 deg at 270's trim (+0.0005 deg forward) where the table comes back
    to 0's place (+0.0001). The file now has a line at 360 deg with 0's deviations and one at -90 deg with
    270's; the trim at 315 deg is halfway between 270's and 0's. Values: the review's log (6-decimal lines,
    exact)."""
    log = _rotary_log([0, 90, 180, 270], [0.0001, 0.0011, -0.0019, 0.0006], [-0.0001, 0.0009, -0.0021, 0.0004])
    rows = _rows(positioning_comp_file(log))
    assert positioning_comp_file(log).splitlines() == [
        "-90.000000 -89.999400 -89.999600", "0.000000 0.000100 -0.000100", "90.000000 90.001100 90.000900",
        "180.000000 179.998100 179.997900", "270.000000 270.000600 270.000400", "360.000000 360.000100 359.999900"]
    tab = JointTable.from_type0(rows)          # (degrees here: the lookup is unit-free)
    for d, at0, at270 in ((1, 0.0001, 0.0006), (-1, -0.0001, 0.0004)):
        # trim = nominal - actual = minus the deviation
        assert tab.trim(np.array([315.0]), d)[0] == pytest.approx(-(at0 + at270) / 2, abs=1e-12)
        assert tab.trim(np.array([360.0]), d)[0] == pytest.approx(-at0, abs=1e-12)
        assert tab.trim(np.array([-45.0]), d)[0] == pytest.approx(-(at0 + at270) / 2, abs=1e-12)
    # a test over the whole turn (0 and 360 both targets) and a linear axis: no line added
    full = _rotary_log([0, 120, 240, 360], [0.0001, 0.0002, 0.0003, 0.0001], [0.0, 0.0, 0.0, 0.0])
    assert [r[0] for r in _rows(positioning_comp_file(full))] == [0.0, 120.0, 240.0, 360.0]
    lin = _rotary_log([0, 90, 180, 270], [0.001] * 4, [0.0] * 4, unit="mm")
    assert [r[0] for r in _rows(positioning_comp_file(lin))] == [0.0, 90.0, 180.0, 270.0]


def test_rotary_file_over_a_range():
    """--comp-range-deg / range_deg: LinuxCNC holds a table's end lines beyond them (no modulo), so a joint
    that turns past last - 360 .. first + 360 (a WRAPPED_ROTARY C counts turns: C350 then C10 is joint 370)
    needs the turn repeated out to its limits. Known answer on review33b's four targets: lines every 90 deg
    from the last at or below LO to the first at or above HI, each the deviations of its angle modulo 360;
    the trim at 420 deg (60 deg's place) is two thirds of the way from 0's to 90's. The range of the two
    closing lines gives the default file byte for byte; a range inside the test adds nothing; a full-turn
    test repeats its first turn [0, 360) and keeps its measured 360 line."""
    log = _rotary_log([0, 90, 180, 270], [0.0001, 0.0011, -0.0019, 0.0006], [-0.0001, 0.0009, -0.0021, 0.0004])
    rows = _rows(positioning_comp_file(log, (-400, 800)))
    assert list(rows[:, 0]) == list(np.arange(-450.0, 811.0, 90.0))
    base = {0: (0.0001, -0.0001), 90: (0.0011, 0.0009), 180: (-0.0019, -0.0021), 270: (0.0006, 0.0004)}
    for nom, fwd, rev in rows:
        up, down = base[int(nom) % 360]
        assert fwd - nom == pytest.approx(up, abs=1e-9) and rev - nom == pytest.approx(down, abs=1e-9)
    tab = JointTable.from_type0(rows)
    assert tab.trim(np.array([420.0]), 1)[0] == pytest.approx(-(0.0001 + (0.0011 - 0.0001) * 2 / 3), abs=1e-12)
    assert tab.trim(np.array([-400.0]), -1)[0] == pytest.approx(-(-0.0001 + (0.0004 + 0.0001) * 4 / 9), abs=1e-12)
    assert positioning_comp_file(log, (-90, 360)) == positioning_comp_file(log)
    assert positioning_comp_file(log, (10, 20)) == comp_text(_rows(positioning_comp_file(log))[1:-1])
    full = _rotary_log([0, 120, 240, 360], [0.0001, 0.0002, 0.0003, 0.0004], [0.0, 0.0, 0.0, 0.0])
    f = _rows(positioning_comp_file(full, (-200, 500)))
    assert list(f[:, 0]) == [-240.0, -120.0, 0.0, 120.0, 240.0, 360.0, 480.0, 600.0]
    # -240 and -120 carry 120's and 240's, 480 and 600 likewise; the measured 360 line stays 0.0004
    assert list(np.round(f[:, 1] - f[:, 0], 6)) == [0.0002, 0.0003, 0.0001, 0.0002, 0.0003, 0.0004, 0.0002, 0.0003]
    lin = _rotary_log([0, 90, 180, 270], [0.001] * 4, [0.0] * 4, unit="mm")
    for bad, msg in (((-400, 800), "for a rotary test"),):
        with pytest.raises(ConfigError, match=msg):
            positioning_comp_file(lin, bad)
    for bad, msg in (((800, -400), "lo < hi"), ((0, float("nan")), "finite"), (("a", 1), "two numbers"),
                     ((-1e6, 1e6), "LinuxCNC takes at most 256"), ((-2e4, 2e4), "LinuxCNC takes at most 256")):
        with pytest.raises(ConfigError, match=msg):
            positioning_comp_file(log, bad)


def test_cli_comp_range(tmp_path, capsys):
    """vmt iso230-2 --comp-file --comp-range-deg: the file of positioning_comp_file(log, range); bad uses one
    line, exit 2, nothing written."""
    from core.positioning import write_positioning_log

    log = write_positioning_log(tmp_path / "c.csv", _rotary_log([0, 90, 180, 270], [0.0001, 0.0011, -0.0019, 0.0006],
                                                               [-0.0001, 0.0009, -0.0021, 0.0004]))
    out = tmp_path / "c.comp"
    assert main(["iso230-2", str(log), "--json", str(tmp_path / "a.json"), "--comp-file", str(out),
                 "--comp-range-deg=-400:800"]) == 0
    from core.positioning import read_positioning_log

    assert out.read_text() == positioning_comp_file(read_positioning_log(log), (-400, 800))
    lin = tmp_path / "x.csv"
    assert main(["simulate", "positioning", "--machine", "vmc-3axis", "--axis", "X", "--out", str(lin)]) == 0
    capsys.readouterr()
    for args, msg in (([str(log), "--comp-range-deg=-400:800"], "--comp-range-deg: give --comp-file too"),
                      ([str(log), "--comp-file", str(tmp_path / "d.comp"), "--comp-range-deg=800:-400"],
                       "expected finite LO < HI in degrees"),
                      ([str(log), "--comp-file", str(tmp_path / "d.comp"), "--comp-range-deg", "10"],
                       "expected finite LO < HI in degrees"),
                      ([str(log), "--comp-file", str(tmp_path / "d.comp"), "--comp-range-deg=-1e6:1e6"],
                       "--comp-range-deg -1e+06:1e+06: rotary_wrap_rows:"),
                      ([str(lin), "--comp-file", str(tmp_path / "d.comp"), "--comp-range-deg=0:10"],
                       "is a test in mm; the range in degrees is for a rotary axis")):
        assert main(["iso230-2", *args, "--json", str(tmp_path / "b.json")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and msg in err and "Traceback" not in err, err
        assert not (tmp_path / "b.json").exists() and not (tmp_path / "d.comp").exists()
