"""Machine files (TOML, vmt-machine/1): built-ins, units, overrides, bad input."""

import hashlib
import math
import re
from pathlib import Path

import numpy as np
import pytest

from sim.errorfuncs import LinearTable, SplineTable
from sim.machine import Machine
from sim.machinefile import MachineFileError, builtin_names, load, loads, resolve
from sim.machines import MACHINES, realistic_errors

README = Path(__file__).resolve().parents[2] / "README.md"


def test_builtins_are_files_with_the_papers_geometry():
    assert set(builtin_names()) == {"vmc-3axis", "mikron-ucp710", "nmv3000"} == set(MACHINES)
    m = resolve("mikron-ucp710").config
    assert m.chain == "[w C' A' b X Y Z (C1) t]"
    assert m.strokes["X"] == (-0.355, 0.355) and m.strokes["Z"] == (-0.1, 0.4)
    assert m.strokes["A"] == pytest.approx((-100 * math.pi / 180, 120 * math.pi / 180), abs=1e-15)
    assert m.rotary_points_R_m["A"] == (0.0, 0.0, -0.12) and m.J_m == (0.0, 0.0, 0.15)
    n = resolve("nmv3000").config
    assert n.chain == "V[w-C-A-b-Y-X-Z-(C)-t]" and n.rotary_points_R_m["A"] == (0.0, 0.0, -0.1)
    v = MACHINES["vmc-3axis"]()
    assert v.strokes == {"X": (-0.3, 0.3), "Y": (-0.2, 0.2), "Z": (-0.05, 0.4)} and not v.errors
    p = resolve("vmc-3axis").probe
    assert p.stylus_r_m == 0.003 and p.sigma_m == pytest.approx(0.125e-6, abs=1e-18)


def test_one_error_override_known_tip():
    """[error.EXX] constant_um = 1 on the table-side X of vmc-3axis: the tool ends 1 um
    further in +X relative to the part (ISO 230-1), everywhere."""
    spec = loads('base = "vmc-3axis"\n[error.EXX]\nconstant_um = 1.0\n')
    assert spec.overrides == ("EXX",) and spec.config.name == "vmc-3axis"
    m = Machine(spec.config)
    lin = np.array([[0.1, -0.1, 0.2], [-0.2, 0.15, 0.0]])
    np.testing.assert_allclose(m.tip_W(lin) - lin, [[1e-6, 0, 0]] * 2, rtol=0, atol=1e-15)


def test_units_in_the_key_names():
    spec = loads('''
base = "nmv3000"
chain = "V[w-C-b-Y-X-Z-(C)-t]"
[error.EXX]
constant_um = 1.0
slope_um_per_m = 20.0
quadratic_um_per_m2 = -100.0
periodic = [{ amplitude_um = 0.5, period_mm = 10.0, phase_deg = 90.0 }]
[error.EYY]
table_mm = [-150, 0, 150]
table_um = [0, 3, 1]
interpolation = "linear"
[error.EZZ]
table_mm = [-100, 0, 100, 325]
table_um = [0, 1, 0, 2]
interpolation = "cubic"
reversal_um = 4.0
[error.ECC]
slope_urad_per_deg = 0.1
[error.EX0C]
constant_um = 15
[error.EC0Y]
constant_urad = -43.4
[error.EXY]
thermal = { offset_um_per_h = 2.0, scale_ppm_per_h = 1.0 }
''')
    c = spec.config
    assert "A" not in c.strokes and set(c.strokes) == {"X", "Y", "Z", "C"}  # the chain dropped A
    x = np.array([0.1])
    assert c.errors["EXX"](x)[0] == pytest.approx(1e-6 + 20e-6 * 0.1 - 100e-6 * 0.01 + 0.5e-6, abs=1e-15)
    assert isinstance(c.errors["EYY"], LinearTable) and c.errors["EYY"](np.array([-0.075]))[0] == pytest.approx(1.5e-6)
    f = c.errors["EZZ"]
    assert isinstance(f.terms[0], SplineTable)
    assert f(np.array([0.0]), direction=np.array([1.0]))[0] == pytest.approx(1e-6 + 2e-6, abs=1e-15)
    assert c.errors["ECC"](np.array([math.radians(90.0)]))[0] == pytest.approx(9e-6, abs=1e-15)
    assert c.errors["EX0C"].value == 15e-6 and c.errors["EC0Y"].value == pytest.approx(-43.4e-6)
    assert c.errors["EXY"](np.array([0.1]), t_s=np.array([1800.0]))[0] == pytest.approx(1e-6 + 0.05e-6, abs=1e-15)


def test_realistic_with_seed_is_the_seeded_set():
    spec = loads('base = "mikron-ucp710"\nerrors = "realistic"\nseed = 7\nripple = false\n')
    cfg = MACHINES["mikron-ucp710"]()
    want = realistic_errors(("A", "C", "X", "Y", "Z"), strokes=cfg.strokes, J_m=cfg.J_m, rng=np.random.default_rng(7),
                            ripple=False)
    lin = np.array([[0.1, -0.05, 0.2]])
    rot = np.array([[0.3, 1.0]])
    a = Machine(spec.config).tip_W(lin, rot)
    b = Machine(MACHINES["mikron-ucp710"](errors=want)).tip_W(lin, rot)
    assert np.array_equal(a, b) and spec.seed == 7 and spec.errors == "realistic"


def _readme_machine_file() -> str:
    text = README.read_text(encoding="utf-8")
    sec = text.split("## Your own machine", 1)[1]
    return re.search(r"```toml\n(.*?)```", sec, re.S).group(1)


def test_readme_example_loads_and_simulates(tmp_path):
    """The README's machine file, as a user copies it, read and probed."""
    p = tmp_path / "my-machine.toml"
    p.write_text(_readme_machine_file())
    spec = load(p)
    from sim.campaign import simulate_campaign

    log = simulate_campaign("cross-pocket", Machine(spec.config), spec.probe, [0.0, 90.0],
                            np.random.default_rng(0), check_collisions=False)
    assert log.ok.all() and log.n > 100


BAD = [
    ("chain = 3\n", "chain: expected a string"),
    ('base = "nope"\n', "base: unknown built-in machine 'nope'"),
    ('base = "vmc-3axis"\nspeed = 3\n', "speed: unknown key"),
    ('base = "vmc-3axis"\nformat = "vmt-machine/9"\n', "format: expected 'vmt-machine/1'"),
    ('chain = "V[w-X-Y-b-Z-(C)-t]"\n[strokes]\nX_mm = [-1, 1]\nY_mm = [-1, 1]\n', r"strokes.Z_mm: missing"),
    ('base = "vmc-3axis"\n[strokes]\nX_mm = [1, -1]\n', r"strokes.X_mm: expected \[min, max\]"),
    ('base = "vmc-3axis"\n[strokes]\nX_deg = [-1, 1]\n', "strokes.X_deg: expected X_mm"),
    ('base = "vmc-3axis"\n[strokes]\nC_deg = [-1, 1]\n', "strokes.C_deg: 'C' is not an axis of the chain"),
    ('base = "vmc-3axis"\n[error.EXX]\nconstant_urad = 1\n', "error.EXX.constant_urad: EXX is a translation; use constant_um"),
    ('base = "vmc-3axis"\n[error.EAX]\nconstant_um = 1\n', "error.EAX.constant_um: EAX is a rotation; use constant_urad"),
    ('base = "vmc-3axis"\n[error.EXX]\nconstant_mm = 1\n', "error.EXX.constant_mm: unknown key"),
    ('base = "vmc-3axis"\n[error.EQQ]\nconstant_um = 1\n', "error.EQQ: unknown ISO"),
    ('base = "vmc-3axis"\n[error.EXC]\nconstant_um = 1\n', "error.EXC: EXC belongs to axis C"),
    ('base = "vmc-3axis"\n[error.EB0X]\nconstant_urad = 1\n', "error.EB0X: EB0X is zero by the ISO 230-1 convention"),
    ('base = "vmc-3axis"\n[error.EC0Y]\nslope_urad_per_m = 1\n', "error.EC0Y.slope_urad_per_m: EC0Y is a location error"),
    ('base = "vmc-3axis"\n[error.EXX]\ntable_mm = [0, 1]\ntable_um = [0, 1]\n', "error.EXX.interpolation: missing"),
    ('base = "vmc-3axis"\n[error.EXX]\ntable_mm = [0, 1]\ntable_um = [0]\ninterpolation = "cubic"\n',
     "error.EXX.table_um: 1 value for 2 positions"),
    ('base = "vmc-3axis"\n[error.EXX]\ntable_mm = [1, 0]\ntable_um = [0, 1]\ninterpolation = "cubic"\n',
     "error.EXX.table_mm: positions must be strictly increasing"),
    ('base = "vmc-3axis"\n[error.EXX]\ntable_mm = [0, 1]\ntable_um = [0, 1]\ninterpolation = "akima"\n',
     "error.EXX.interpolation: expected"),
    ('base = "vmc-3axis"\n[error.EXX]\nperiodic = [{ amplitude_um = 1 }]\n', r"error.EXX.periodic\[0\].period_mm: missing"),
    ('base = "vmc-3axis"\n[error.EXX]\nperiodic = [{ amplitude_um = 1, period_mm = 0 }]\n', "must be > 0"),
    ('base = "vmc-3axis"\n[error.EXX]\nreversal_um = -1\n', "error.EXX.reversal_um: must be >= 0"),
    ('base = "vmc-3axis"\n[error.EXX]\nreversal_um = 1\nreversal_sense = "behind"\n',
     "error.EXX.reversal_sense: expected"),
    ('base = "vmc-3axis"\n[error.EXX]\nreversal_sense = "lag"\n', "error.EXX.reversal_sense: needs reversal_um"),
    ('base = "vmc-3axis"\n[error.EAX]\nthermal = { scale_ppm_per_h = 1 }\n', "error.EAX.thermal.scale_ppm_per_h: unknown key"),
    ('base = "vmc-3axis"\n[error.EXX]\n', "error.EXX: no terms"),
    ('base = "vmc-3axis"\n[probe]\nnoise_um = -1\n', "probe.noise_um: must be >= 0"),
    ('base = "vmc-3axis"\n[probe]\nradius_mm = 3\n', "probe.radius_mm: unknown key"),
    ('base = "vmc-3axis"\n[probe]\nlobing = [{ k = 0, cos_um = 1 }]\n', r"probe.lobing\[0\].k: expected an integer >= 1"),
    ('base = "vmc-3axis"\n[tool]\noffset_mm = [0, 150]\n', "tool.offset_mm: expected 3 numbers"),
    ('base = "vmc-3axis"\nseed = 3\n', 'seed: only with errors = "realistic"'),
    ('base = "vmc-3axis"\nerrors = "some"\n', "errors: expected"),
    ('base = "vmc-3axis"\nchain = "[w-X-b-Q-t]"\n', "chain: chain '\\[w-X-b-Q-t\\]': unknown token"),
    ("base = \n", "not TOML"),
    # review30 F3: magnitudes beyond the bounds (MAX_ANGULAR_URAD, MAX_LINEAR_UM), the unit named
    ('base = "vmc-3axis"\n[error.EC0Y]\nconstant_urad = -20000000.0\n',
     r"error.EC0Y: reaches -2e\+07 urad: beyond the \+-1000 urad a machine file's rotation error may have"),
    ('base = "vmc-3axis"\n[error.EXX]\nslope_um_per_m = 5000\n',    # 5 mm/m over X -300..300 mm
     r"error.EXX: reaches -1500 um \(at X -300 mm\): beyond the \+-1000 um"),
    ('base = "vmc-3axis"\n[error.EAX]\nperiodic = [{ amplitude_urad = 1001, period_mm = 20 }]\n',
     r"error.EAX: reaches .*urad \(at X .* mm\): beyond the \+-1000 urad"),
    ('base = "vmc-3axis"\n[error.EXX]\nthermal = { offset_um_per_h = 200 }\n',    # 1600 um after 8 h
     r"error.EXX: reaches 1600 um \(at X .* mm, after 8 h\)"),
]


@pytest.mark.parametrize("text, match", BAD)
def test_bad_file_names_the_key(text, match):
    with pytest.raises(MachineFileError, match=match) as e:
        loads(text, source="m.toml")
    msg = str(e.value)
    assert msg.startswith("m.toml: ") and "\n" not in msg


def test_missing_file_and_unknown_name(tmp_path):
    with pytest.raises(MachineFileError, match="no such machine file"):
        load(tmp_path / "nope.toml")
    with pytest.raises(MachineFileError, match="not a built-in machine"):
        resolve("nope")


def test_errors_label_says_what_errors_a_machine_file_has(tmp_path):
    # a file on base set none with [error.*] tables has those errors, not "none" (the label said
    # "machine file (none)"); a drawn set names its seed; a built-in machine names its set
    from sim.machinefile import errors_label, truth_machine

    p = tmp_path / "m.toml"
    p.write_text('base = "vmc-3axis"\nerrors = "none"\n[error.EXX]\nconstant_um = 1.0\n'
                 '[error.EC0Y]\nconstant_urad = 5.0\n')
    # the file's name and its bytes' SHA-256 prefix, not the writer's directories
    sha = hashlib.sha256(p.read_bytes()).hexdigest()[:12]
    label = errors_label(str(p), truth_machine(str(p)))
    assert label == f"machine file m.toml (sha256 {sha}): EXX, EC0Y set on base none"
    assert str(tmp_path) not in label
    p.write_text('base = "nmv3000"\nerrors = "realistic"\nseed = 3\n')
    sha2 = hashlib.sha256(p.read_bytes()).hexdigest()[:12]
    assert sha2 != sha
    assert errors_label(str(p), truth_machine(str(p))) == f"machine file m.toml (sha256 {sha2}): base realistic, seed 3"
    assert errors_label("nmv3000", truth_machine("nmv3000", "study")) == "study"


def test_a_lagging_reversal_in_a_machine_file():
    """``reversal_sense = "lag"``: the axis stops short of its reading by half the lost motion (ISO 230-2's
    ``B_i = -reversal_um``); without the key the reversal leads, as before."""
    from core import iso
    from sim.errorfuncs import Reversal
    from sim.machinefile import describe_error

    lag = loads('base = "vmc-3axis"\n[error.EXX]\nreversal_um = 4.0\nreversal_sense = "lag"\n').config.errors["EXX"]
    lead = loads('base = "vmc-3axis"\n[error.EXX]\nreversal_um = 4.0\n').config.errors["EXX"]
    assert lag == Reversal(4e-6, "lag") and lead == Reversal(4e-6)
    d = np.array([1.0, -1.0])
    assert np.allclose(lag(np.zeros(2), direction=d), [-2e-6, 2e-6], atol=1e-18)
    assert np.allclose(lead(np.zeros(2), direction=d), [2e-6, -2e-6], atol=1e-18)
    sym = iso.symbol("EXX")
    assert describe_error(lag, sym) == "reversal 4 um, lag" and describe_error(lead, sym) == "reversal 4 um"


def test_error_bounds_are_inclusive_and_the_realistic_sets_far_inside():
    """The bounds themselves load (a machine file may reach them); the built-ins' realistic sets are 10x inside."""
    from sim.machinefile import MAX_ANGULAR_URAD, MAX_LINEAR_UM

    ok = loads(f'base = "vmc-3axis"\n[error.EC0Y]\nconstant_urad = {-MAX_ANGULAR_URAD}\n'
               f'[error.EXX]\nconstant_um = {MAX_LINEAR_UM}\n', source="m.toml")
    assert ok.config.errors["EC0Y"].value == pytest.approx(-1e-3)
    from core import iso

    worst = {True: 0.0, False: 0.0}      # the docstring's figures: 98.6 urad, 38.2 um over 31 seeds
    for name in ("vmc-3axis", "mikron-ucp710", "nmv3000"):
        cfg = resolve(name).config
        for seed in range(5):
            for k, f in realistic_errors(tuple(cfg.strokes), strokes=cfg.strokes, J_m=cfg.J_m,
                                         rng=np.random.default_rng(seed)).items():
                s = iso.symbol(k)
                p = np.linspace(*cfg.strokes[s.axis], 201)
                v = np.max(np.abs(f(p, np.zeros_like(p), np.ones_like(p)))) / 1e-6
                worst[s.angular] = max(worst[s.angular], v)
    assert 50 < worst[True] < MAX_ANGULAR_URAD / 5 and 20 < worst[False] < MAX_LINEAR_UM / 5, worst


def test_polynomial_terms_are_of_the_axis_position_as_documented():
    """review30b F5: sim/machinefile.py's docstring (and README's) says the terms are functions of the axis
    position q = reading + J, with this example: EZZ slope 10 um/m and a 150 mm tool offset along Z give
    1.5 um at reading Z = 0 (1.5 um = 10 um/m x 0.150 m; at the reading it would be 0). Exact to rounding."""
    import numpy as np

    from sim.machine import Machine
    from sim.machinefile import __doc__ as doc, loads

    spec = loads('''format = "vmt-machine/1"
name = "poly"
chain = "V[w-X-Y-b-Z-(C)-t]"
[strokes]
X_mm = [-300, 300]
Y_mm = [-200, 200]
Z_mm = [-50, 400]
[tool]
offset_mm = [0, 0, 150]
[error.EZZ]
slope_um_per_m = 10.0
''', "poly.toml")
    m = Machine(spec.config)
    v = m.error_values(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]]))["EZZ"]
    np.testing.assert_allclose(v, [1.5e-6, 2.5e-6], rtol=1e-12)
    assert "polynomial in the\n  axis position" in doc and "1.5 um at reading Z = 0" in doc
