"""``--machine FILE`` wherever a machine is named, and ``vmt machine show``."""

import hashlib
import subprocess
import sys

import numpy as np
import pytest

from core.probelog import read_probe_log
from scenarios.cli import main

MY = """
base = "vmc-3axis"
name = "my-vmc"
[error.EXX]
constant_um = 1.0
[probe]
noise_um = 0.0
"""


@pytest.fixture
def my_file(tmp_path):
    p = tmp_path / "my.toml"
    p.write_text(MY)
    return p


def test_show_prints_chain_strokes_errors_and_tip_deviations(my_file, capsys):
    assert main(["machine", "show", str(my_file)]) == 0
    out = capsys.readouterr().out
    assert "chain V[w-X-Y-b-Z-(C)-t]: workpiece side Y, X" in out
    assert "X -300..300 mm" in out and "EXX   um   constant 1 um" in out
    # the tip deviation table: +1 um in X at every point (ISO: tool relative to the part)
    rows = [ln.split() for ln in out.splitlines()[-9:]]
    assert all(float(r[3]) == pytest.approx(1.0, abs=1e-6) and float(r[4]) == 0.0 for r in rows)
    assert main(["machine", "show", "nmv3000"]) == 0
    assert "errors (ISO 230-1" in capsys.readouterr().out


def test_show_gives_each_error_range_at_the_axis_positions(tmp_path, capsys):
    """An error's range is over the stroke at the axis positions reading + J (review27b F4): EZZ
    100 um/m on vmc-3axis (Z -50..400 mm readings, J_Z 150 mm) spans 10..55 um at Z 100..550 mm,
    not -5..40 um at the readings; EXX (J_X 0) keeps its stroke."""
    f = tmp_path / "z.toml"
    f.write_text('base = "vmc-3axis"\nname = "z"\nerrors = "none"\n[error.EZZ]\nslope_um_per_m = 100.0\n'
                 '[error.EXX]\nconstant_um = 1.0\n')
    assert main(["machine", "show", str(f)]) == 0
    out = capsys.readouterr().out
    assert "tool offset J (gauge point - tip centre): (0, 0, 150) mm" in out
    assert "[+10.000 .. +55.000] over the stroke + J (Z 100..550 mm, axis positions)" in out, out
    assert "[+1.000 .. +1.000] over the stroke + J (X -300..300 mm, axis positions)" in out, out


def test_simulate_with_a_machine_file_reads_minus_one_um_on_x_faces(my_file, tmp_path, capsys):
    """The file's EXX = +1 um against the same campaign on the perfect built-in
    (same part, form errors and all): every X-face touch 1 um short."""
    out, ref = tmp_path / "log.csv", tmp_path / "ref.csv"
    assert main(["simulate", "cross-pocket", "--machine", str(my_file), "--out", str(out),
                 "--no-collision-check"]) == 0
    said = capsys.readouterr().out
    assert "machine my-vmc" in said
    # the log says what errors the machine has: the file's EXX on its base's none (was "machine file (none)")
    # (the file's name and SHA-256 prefix, not the path it was given by)
    label = f"machine file {my_file.name} (sha256 {hashlib.sha256(my_file.read_bytes()).hexdigest()[:12]})"
    assert read_probe_log(out).meta["errors"] == f"{label}: EXX set on base none"
    assert f"errors {label}: EXX set on base none" in said
    assert main(["simulate", "cross-pocket", "--machine", "vmc-3axis", "--errors", "none", "--noise-um", "0",
                 "--out", str(ref), "--no-collision-check"]) == 0
    log, base = read_probe_log(out), read_probe_log(ref)
    x = np.abs(log.normals()[:, 0]) > 1 - 1e-12
    assert x.sum() > 20
    d = log.positions_mm()[x] - base.positions_mm()[x]
    np.testing.assert_allclose(d, np.tile([-1e-3, 0, 0], (x.sum(), 1)), rtol=0, atol=1e-6)


def test_program_limits_from_a_machine_file(my_file, tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    assert main(["simulate", "cross-pocket", "--machine", "vmc-3axis", "--plan-only", "--out", str(plan),
                 "--no-collision-check"]) == 0
    ngc = tmp_path / "p.ngc"
    # (safe Z 80: at 50 the sphere's top touches start at 52.7 mm and the rise would be a descent onto the sphere,
    # refused since session 25)
    assert main(["machine", "program", "--plan", str(plan), "--out", str(ngc), "--machine", str(my_file),
                 "--safe-z-mm", "80"]) == 0
    assert ngc.read_text().count("G38.2") > 50
    assert main(["machine", "program", "--plan", str(plan), "--out", str(ngc), "--machine", str(my_file),
                 "--limits-mm", "X-1:1,Y-1:1,Z-1:1"]) == 2
    assert "give one" in capsys.readouterr().err


#: (argv, the one-line error it must give, run as a real process): the first case of each command is a real
#: process (its exit status; no traceback on stderr), the others go through ``main`` in this process (a
#: traceback there would be an exception), which spares a Python start-up each (about 1 s of CPU)
BAD_MACHINE_CASES = [
    (["machine", "show", "{bad}"], "error.EXX.constant_urad: EXX is a translation; use constant_um", True),
    (["simulate", "cross-pocket", "--machine", "{bad}", "--out", "{tmp}/o.csv"], "error.EXX.constant_urad", True),
    (["simulate", "cross-pocket", "--machine", "{my}", "--errors", "none", "--out", "{tmp}/o.csv"],
     "--errors: the machine file", False),
    (["scenario", "mfb-3axis", "--machine", "nmv3000"], "is not the mfb-3axis plan's", False),
    (["scenario", "pin-circle", "--machine", "{my}"],
     "--machine: pin-circle does not take it; it is for mfb-3axis, mfb-5axis", True),
    (["scenario", "mfb-3axis", "--apply-comp", "{tmp}"], "no X.comp, Y.comp, Z.comp or mfb-3axis-comp.json", False),
    (["machine", "serve", "--port", "0", "--machine", "{bad}", "--scene", "cross-pocket"], "error.EXX", True),
    (["machine", "show", "{tmp}/none.toml"], "no such machine file", False),
]


def test_each_command_has_a_real_process_case():
    cmd = lambda a: tuple(a[:2] if a[0] == "machine" else a[:1])  # noqa: E731
    assert {cmd(a) for a, _, p in BAD_MACHINE_CASES if p} == {cmd(a) for a, _, _ in BAD_MACHINE_CASES}


@pytest.mark.parametrize("argv, match, process", BAD_MACHINE_CASES)
def test_bad_machine_file_one_line_exit_2(argv, match, process, my_file, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('base = "vmc-3axis"\n[error.EXX]\nconstant_urad = 1\n')
    argv = [a.format(bad=bad, my=my_file, tmp=tmp_path) for a in argv]
    if process:
        r = subprocess.run([sys.executable, "-m", "scenarios.cli", *argv], capture_output=True, text=True)
        rc, err = r.returncode, r.stderr
    else:
        rc, err = main(argv), capsys.readouterr().err
    assert rc == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert match in err
