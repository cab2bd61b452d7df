"""A machine file written from the README's key list alone ("Your own machine"), checked from outside
(audit37): the tip deviations `vmt machine show` prints against a hand formula, and a periodic term's
range seen at its peaks, whatever its period (even samples alias a period near a multiple of their step).
"""

import math

import numpy as np
import pytest

from scenarios.cli import main
from tests.cli_helpers import one_line_error

# every key the README names for a linear machine, as a shop would write them (errors "none" underneath)
SHOP = """
format = "vmt-machine/1"
name = "shop-vmc3"
base = "vmc-3axis"
errors = "none"

[strokes]
X_mm = [-250, 250]
Y_mm = [-200, 200]
Z_mm = [-300, 100]

[tool]
offset_mm = [0, 0, 150]

[probe]
stylus_radius_mm = 1.5
pretravel_um = 0.4
pretravel_axial_um = 0.8
noise_um = 0.2
max_travel_mm = 5.0

[error.EXX]
slope_um_per_m = 20.0
quadratic_um_per_m2 = 5.0
cubic_um_per_m3 = -2.0

[error.EYY]
table_mm = [-200, 0, 200]
table_um = [0.0, 2.0, 0.0]
interpolation = "linear"

[error.EC0Y]
constant_urad = 30.0

[error.EBX]
periodic = [{ amplitude_urad = 2.0, period_mm = 50.0, phase_deg = 30.0 }]
"""


def _hand(x_mm, y_mm, z_mm):
    """The tip deviation (tool relative to the part, um) by the README's definitions, first order:
    EXX a polynomial in the axis position q = reading + J (J_X = 0: q = x) in m; EC0Y's -y * EC0Y in X
    (CONTRIBUTING.md, "Error conventions"); EBX a right-handed rotation of the tool relative to the part
    about +Y, which moves a point z below the X carriage's frame by EBX * z in X (x' = x + beta z); EYY a
    linear table in Y."""
    x, y, z = x_mm / 1e3, y_mm / 1e3, z_mm / 1e3
    exx = 20.0 * x + 5.0 * x ** 2 - 2.0 * x ** 3
    ebx = 2.0 * math.sin(2 * math.pi * x_mm / 50.0 + math.radians(30.0))        # urad
    eyy = 2.0 * (1 - abs(y_mm) / 200.0)
    return exx - y * 30.0 + ebx * z, eyy, 0.0


def test_show_prints_the_hand_worked_tip_deviation(tmp_path, capsys):
    """The nine corners and centre `machine show` prints, against _hand: to its 3 printed decimals
    (0.0005 um) plus the second-order terms the hand formula leaves out (EC0Y^2 y / 2, EBX^2 z / 2: below
    1e-5 um here); 0.002 um allows the rounding of the printed positions' 0.1 mm too (EXX' 20 um/m)."""
    p = tmp_path / "shop.toml"
    p.write_text(SHOP)
    assert main(["machine", "show", str(p)]) == 0
    out = capsys.readouterr().out
    assert "EC0Y  urad constant 30 urad" in out
    rows = [[float(v) for v in ln.split()] for ln in out.splitlines()[-9:]]
    assert len(rows) == 9
    for x, y, z, dx, dy, dz in rows:
        hx, hy, hz = _hand(x, y, z)
        assert dx == pytest.approx(hx, abs=2e-3), (x, y, z)
        assert dy == pytest.approx(hy, abs=2e-3), (x, y, z)
        assert dz == pytest.approx(hz, abs=2e-3), (x, y, z)
    # the sign a metrologist checks first: +30 urad squareness, the tool at +Y leans to -X
    at = {(x, y, z): dx for x, y, z, dx, *_ in rows}
    assert at[(-250.0, 200.0, 100.0)] < at[(-250.0, -200.0, 100.0)]


@pytest.mark.parametrize("period_mm, phase_deg", [(6.0, 0.0), (0.6, 0.0), (10.0, 0.0), (0.02, 17.0)])
def test_show_prints_a_ripples_whole_range(tmp_path, capsys, period_mm, phase_deg):
    """A 5 um ripple on X's 600 mm stroke: printed as [-5.000 .. +5.000] at every period. Before audit37 the
    range came from 201 even samples (3 mm apart): period 6 mm printed [-0.000 .. +0.000], 10 mm [-4.755 ..
    +4.755] (the 0.6 and 0.02 mm periods also alias on the 2001 samples of the bound check)."""
    p = tmp_path / "rip.toml"
    p.write_text('format = "vmt-machine/1"\nbase = "vmc-3axis"\nerrors = "none"\n[error.EXX]\n'
                 f"periodic = [{{ amplitude_um = 5.0, period_mm = {period_mm}, phase_deg = {phase_deg} }}]\n")
    assert main(["machine", "show", str(p)]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.strip().startswith("EXX"))
    assert "[-5.000 .. +5.000]" in line, line


def test_a_ripple_beyond_the_bound_is_refused_at_any_period(tmp_path, capsys):
    """1500 um at a period of 0.6 mm reaches 1500 um, beyond the +-1000 um a machine file's translation may
    have: refused in one line naming the key. Before audit37 the bound check's 2001 even samples over the
    600 mm stroke fell every 0.3 mm, on the ripple's zeros, and the file was read (1.5 mm of error)."""
    from sim.errorfuncs import Periodic

    f = Periodic(1500e-6, 0.6e-3)
    assert np.abs(f(np.linspace(-0.3, 0.3, 2001))).max() < 1e-9      # what the even samples alone saw
    p = tmp_path / "big.toml"
    p.write_text('format = "vmt-machine/1"\nbase = "vmc-3axis"\nerrors = "none"\n[error.EXX]\n'
                 "periodic = [{ amplitude_um = 1500.0, period_mm = 0.6 }]\n")
    assert main(["machine", "show", str(p)]) == 2
    one_line_error(capsys, "big.toml", "error.EXX", "reaches 1500 um", "+-1000 um")
    # at 900 um it is within the bound and read
    p.write_text(p.read_text().replace("1500.0", "900.0"))
    assert main(["machine", "show", str(p)]) == 0
    assert "[-900.000 .. +900.000]" in capsys.readouterr().out


def test_a_rotary_ripple_is_seen_at_its_peaks(tmp_path, capsys):
    """The same on a rotary axis (positions and period in rad inside): ECC 500 urad at a period of 0.36 deg
    over C's -360..360 deg (2001 even samples 0.36 deg apart, on its zeros) is within the bound and shown
    whole; 1500 urad is refused."""
    p = tmp_path / "c.toml"
    body = ('format = "vmt-machine/1"\nbase = "nmv3000"\nerrors = "none"\n[error.ECC]\n'
            "periodic = [{ amplitude_urad = AMP, period_deg = 0.36 }]\n")
    p.write_text(body.replace("AMP", "500.0"))
    assert main(["machine", "show", str(p)]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.strip().startswith("ECC"))
    assert "[-500.000 .. +500.000]" in line, line
    p.write_text(body.replace("AMP", "1500.0"))
    assert main(["machine", "show", str(p)]) == 2
    one_line_error(capsys, "error.ECC", "reaches", "1000 urad")
