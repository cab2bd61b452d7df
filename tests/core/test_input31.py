"""A file ``vmt check`` accepts is a file every command reads right (session 31, input31; review31 F3, F5, F6, F9,
F13, F14).

The reviewer wrote files from the docs and checked them against shared/spec/probe-log.md and
positioning-log.md. Each test below quotes the spec's words it holds the reader to. ``mylog.csv`` (data/input31)
is review31's hand-written square-pocket campaign (4 set-ups C 0/75/130/210, 144 touches, every optional
column filled); the variants with empty cells are made from it here, cell for cell as the reviewer made them.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest

from core.exceptions import ConfigError, ProbeLogError
from core.features import log_stylus_r_mm
from core.positioning import PositioningLogError, arrange, parse_positioning_log
from core.probelog import parse_probe_log, read_probe_log
from scenarios.cli import main

DATA = Path(__file__).parent / "data" / "input31"
MYLOG = DATA / "mylog.csv"
HEAD = "setup,target,t_s,X_mm,Y_mm,Z_mm,Xn_mm,Yn_mm,Zn_mm,nx,ny,nz"


def blanked(path: Path, out: Path, cells: dict[str, list[int]]) -> Path:
    """``path`` with the cells of each column in ``cells`` emptied at those 0-based data rows (metadata kept)."""
    text = path.read_text()
    lines = text.splitlines()
    h = next(i for i, s in enumerate(lines) if not s.startswith("#"))
    header = lines[h].split(",")
    rows = list(csv.reader(io.StringIO("\n".join(lines[h + 1:]))))
    for name, rs in cells.items():
        j = header.index(name)
        for r in rs:
            rows[r][j] = ""
    out.write_text("\n".join(lines[:h + 1] + [",".join(r) for r in rows]) + "\n")
    return out


def same_columns(a, b) -> None:
    assert list(a.columns) == list(b.columns)
    for k in a.columns:
        x, y = a.columns[k], b.columns[k]
        if x.dtype == object:
            assert list(x) == list(y), k
        else:
            np.testing.assert_array_equal(x, y, err_msg=k)   # exact: the default is the value the file left out


# ---- F3: empty cells of optional columns with a default -------------------------------------------------------


def test_empty_approach_cells_are_the_reversed_normal_and_every_command_sees_the_filled_log(tmp_path, capsys):
    """Spec: ``dx, dy, dz`` | unit approach direction of the stylus at the trigger | default ``-(nx, ny, nz)``.

    review31 F3: with the three cells of C75's first three rows empty, ``vmt check`` said valid and the reader
    kept NaN: ``discover`` stopped with numpy's LinAlgError, ``identify`` wrote "every pre-travel lobe order
    k = 1..6 leaves a residual (none absorbed)" where the filled file has k = 1,2,3,5,6 100 % absorbed. Those
    rows' approach in mylog.csv is the reversed normal, so the log read with the cells empty (three rows, or
    every row) is the filled log to the last bit, and identify writes the same JSON but for the file's name.
    """
    full = read_probe_log(MYLOG)
    d_full = np.column_stack([full.columns[c] for c in ("dx", "dy", "dz")])
    n_full = full.normals()
    assert np.array_equal(d_full[36:39], -n_full[36:39])   # (the reviewer's rows: the default is the truth)
    some = blanked(MYLOG, tmp_path / "emptyD.csv", {c: [36, 37, 38] for c in ("dx", "dy", "dz")})
    every = blanked(MYLOG, tmp_path / "allD.csv", {c: list(range(full.n)) for c in ("dx", "dy", "dz")})
    same_columns(read_probe_log(some), full)
    log = read_probe_log(every)
    np.testing.assert_array_equal(np.column_stack([log.columns[c] for c in ("dx", "dy", "dz")]), -log.normals())
    out = {}
    for name, p in (("full", MYLOG), ("some", some), ("every", every)):
        js = tmp_path / f"{name}.json"
        assert main(["identify", str(p), "--json", str(js)]) == 0
        rep = json.loads(js.read_text())
        rep.pop("log", None)
        out[name] = rep
        capsys.readouterr()
    assert out["some"] == out["full"] and out["every"] == out["full"]
    lobes = out["full"]["not_covered"]["pretravel_lobes"]
    assert lobes   # the block the empty cells made vanish


def test_empty_approach_cells_discover_runs_as_on_the_filled_log(tmp_path, capsys):
    """review31 F3: ``vmt discover`` on the three-row file raised numpy's LinAlgError (a traceback), on the
    every-row file "absorbed_lobes: phi must be a non-empty finite (n,) array" (no file named). Spec default
    ``-(nx, ny, nz)``: the same report as the filled file."""
    some = blanked(MYLOG, tmp_path / "emptyD.csv", {c: [36, 37, 38] for c in ("dx", "dy", "dz")})
    reps = []
    for p in (MYLOG, some):
        js = tmp_path / (p.stem + ".json")
        assert main(["discover", str(p), "--json", str(js)]) == 0
        rep = json.loads(js.read_text())
        rep.pop("log", None)
        reps.append(rep)
    capsys.readouterr()
    assert reps[0] == reps[1]


def test_an_empty_rotary_cell_is_zero_with_a_warning_and_identify_names_the_rows(tmp_path, capsys):
    """Spec: ``A_deg``, ``B_deg``, ``C_deg`` | rotary axis positions during the touch | default ``0``.

    review31 F3: one empty C_deg cell in set-up C75 was NaN: check listed C 0, 75, 130, 210 hiding it, identify
    did the work and then refused "rotary[1].c_deg is nan" naming no row (np.ptp(nan) > 1e-9 is False). The
    cell is now 0, the spec's default, as the column absent would be; check warns that an empty angle sits
    beside written ones (row and line named), and identify refuses the set-up whose C varies, naming its rows.
    """
    p = blanked(MYLOG, tmp_path / "emptyC.csv", {"C_deg": [36]})
    log = read_probe_log(p)
    c = log.columns["C_deg"]
    assert c[36] == 0.0 and not np.isnan(c).any()
    assert c[37] == 75.0
    assert log.warnings == (f"{p}: row 36 (line 44): column 'C_deg' is empty: read as 0, the format's default "
                            "(1 empty cell of 144)",)
    assert main(["check", str(p)]) == 0
    assert "column 'C_deg' is empty: read as 0" in capsys.readouterr().out
    js = tmp_path / "id.json"
    assert main(["identify", str(p), "--json", str(js)]) == 2
    err = capsys.readouterr().err
    # the reader's warning first (warn31: every command says it), then the refusal it explains
    assert err == (f"vmt identify: warning: {log.warnings[0]}\n"
                   f"vmt identify: error: {p}: set-up 'C75': C varies within the set-up (0..75 deg: row 36 at 0, "
                   "row 37 at 75); one indexing per set-up\n")
    assert not js.exists()
    # a column left empty throughout is the column absent: 0, no warning
    every = read_probe_log(blanked(MYLOG, tmp_path / "noC.csv", {"C_deg": list(range(log.n))}))
    assert not every.columns["C_deg"].any() and every.warnings == ()


# ---- F9: an empty stylus_r_mm cell -----------------------------------------------------------------------------


STYLUS = f"""# format: probe-log/1
{{meta}}{HEAD},stylus_r_mm
S1,T1,1.0,10.0,0.0,0.0,10.0,0.0,0.0,1,0,0,1.5
S1,T2,2.0,0.0,10.0,0.0,0.0,10.0,0.0,0,1,0,{{cell}}
S1,T3,3.0,-10.0,0.0,0.0,-10.0,0.0,0.0,-1,0,0,1.5
"""


def test_an_empty_stylus_cell_is_the_metadata_radius_and_fit_refuses_the_mixed_radii(tmp_path, capsys):
    """Spec: ``stylus_r_mm`` | stylus tip radius | default: metadata ``stylus_r_mm``.

    review31 F9 (p/stylus_empty_cell.csv: column 1.5, empty, 1.5; metadata 2): ``vmt fit circle`` dropped the
    column and applied 2 mm to every touch (radius 8.0000, the filled file's 8.5000), "the log's stylus_r_mm
    metadata". The empty cell is 2 mm: two radii in one feature, the existing refusal, now naming the rows.
    Without the metadata line the empty row has no radius: refused naming it (before: "says no stylus radius"
    though the column holds 1.5).
    """
    log = parse_probe_log(STYLUS.format(meta="# stylus_r_mm: 2\n", cell=""), "s.csv")
    np.testing.assert_array_equal(log.columns["stylus_r_mm"], [1.5, 2.0, 1.5])
    with pytest.raises(ConfigError, match=r"^s\.csv: the touches of this feature have different stylus radii "
                       r"\(row 0: 1\.5 mm, row 1: 2 mm; an empty stylus_r_mm cell is the metadata's 2 mm\)$"):
        log_stylus_r_mm(log, np.ones(3, bool))
    bare = parse_probe_log(STYLUS.format(meta="", cell=""), "s.csv")
    assert np.isnan(bare.columns["stylus_r_mm"][1])
    with pytest.raises(ConfigError, match=r"^s\.csv: row 1: stylus_r_mm is empty and there is no stylus_r_mm "
                       r"metadata, but row 0 of this feature has 1\.5 mm"):
        log_stylus_r_mm(bare, np.arange(3))
    assert log_stylus_r_mm(bare, np.array([0, 2])) == (1.5, "column")   # rows that have one
    filled = parse_probe_log(STYLUS.format(meta="# stylus_r_mm: 2\n", cell="1.5"), "s.csv")
    assert log_stylus_r_mm(filled, np.ones(3, bool)) == (1.5, "column")
    f = tmp_path / "s.csv"
    f.write_text(STYLUS.format(meta="# stylus_r_mm: 2\n", cell=""))
    assert main(["fit", "circle", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{f}: the touches of this feature have different stylus radii (row 0" in err


# ---- F5: approach direction into the surface ------------------------------------------------------------------


def approach_log(d1: str) -> str:
    return (f"# format: probe-log/1\n{HEAD},dx,dy,dz\n"
            "S1,T1,1.0,10.0,0.0,0.0,10.0,0.0,0.0,1,0,0,-1,0,0\n"
            f"S1,T2,2.0,0.0,10.0,0.0,0.0,10.0,0.0,0,1,0,{d1}\n")


@pytest.mark.parametrize("d, way, angle", [("0,1,0", "out of", "0"), ("1,0,0", "tangential to", "90"),
                                           ("0.6,0.8,0", "out of", "36.87")])
def test_an_approach_not_into_the_surface_is_refused_naming_the_row(tmp_path, capsys, d, way, angle):
    """Spec: ``nx, ny, nz`` | nominal unit normal ... pointing out of the material (towards the stylus);
    ``dx, dy, dz`` | unit approach direction of the stylus at the trigger (default ``-(nx, ny, nz)``).

    A stylus triggers moving into the material: d . n < 0. review31 F5: d = +n (p/approach_same_as_normal.csv)
    or tangential read without a word. Refused, naming the row and line and the angle to the outward normal.
    """
    with pytest.raises(ProbeLogError, match=rf"^a\.csv: row 1 \(line 4\): approach direction \(dx,dy,dz\) "
                       rf"\({d.replace(',', ', ')}\) points {way} the surface: its angle to the normal \(nx,ny,nz\) "
                       rf"pointing out of the material is {angle} deg"):
        parse_probe_log(approach_log(d), "a.csv")
    f = tmp_path / "a.csv"
    f.write_text(approach_log(d))
    assert main(["check", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"vmt check: error: {f}: row 1 (line 4): approach direction") and err.count("\n") == 1


def test_an_oblique_approach_into_the_surface_reads():
    """Any direction with a component into the material reads (89 deg off the reversed normal too: the reader
    judges what cannot trigger, not how well)."""
    c, s = float(np.cos(np.radians(89.0))), float(np.sin(np.radians(89.0)))
    log = parse_probe_log(approach_log(f"{s!r},{-c!r},0"), "a.csv")
    assert log.columns["dy"][1] == -c


def test_an_outward_approach_on_a_row_that_is_not_a_touch_is_a_warning(tmp_path, capsys):
    """A no_trigger row triggered nowhere: its (dx,dy,dz) is what the machine did when it gave up (a retract), read
    by no analysis. Session 31 refused the whole file for it (review31e, notrig_out.csv); since session 32 it is a
    warning naming the row, the file is read, and an ok row with the same direction is still refused."""
    text = (f"# format: probe-log/1\n{HEAD},dx,dy,dz,status\n"
            "S1,T1,1.0,10.0,0.0,0.0,10.0,0.0,0.0,1,0,0,-1,0,0,ok\n"
            "S1,T2,2.0,0.0,10.0,0.0,0.0,10.0,0.0,0,1,0,0,1,0,{status}\n")
    log = parse_probe_log(text.format(status="no_trigger"), "a.csv")
    assert log.n == 2 and list(log.columns["status"]) == ["ok", "no_trigger"]
    assert log.warnings == ("a.csv: row 1 (line 4): status 'no_trigger': approach direction (dx,dy,dz) (0, 1, 0) "
                            "points out of the surface: its angle to the normal (nx,ny,nz) pointing out of the "
                            "material is 0 deg; kept (the row is not a touch, no analysis reads its direction)",)
    with pytest.raises(ProbeLogError, match=r"^a\.csv: row 1 \(line 4\): approach direction"):
        parse_probe_log(text.format(status="OK"), "a.csv")
    f = tmp_path / "a.csv"
    f.write_text(text.format(status="no_trigger"))
    assert main(["check", str(f)]) == 0
    assert "warning  " in capsys.readouterr().out


# ---- F6: status words ------------------------------------------------------------------------------------------


def test_ok_in_any_case_is_ok(tmp_path, capsys):
    """Spec: ``status`` | ``ok``, or why the touch is not valid (``no_trigger``, ``early_trigger``, ``alarm``,
    ...) | default ``ok``.

    review31 F6 (p/status_OK_case.csv: OK, Ok, ok): "3 (1 ok)", two touches left out without a word. ``OK`` says
    the touch is valid in any case: read as ``ok`` (stored ``ok``, so every command that compares the word
    agrees), also as a last row without an end of line (a whole word, not a torn one).
    """
    text = (f"# format: probe-log/1\n{HEAD},status\nS1,T1,1.0,10.0,0.0,0.0,10.0,0.0,0.0,1,0,0,OK\n"
            "S1,T2,2.0,0.0,10.0,0.0,0.0,10.0,0.0,0,1,0,Ok\nS1,T3,3.0,-10.0,0.0,0.0,-10.0,0.0,0.0,-1,0,0,ok\n")
    log = parse_probe_log(text, "s.csv")
    assert log.ok.all() and list(log.columns["status"]) == ["ok"] * 3
    assert parse_probe_log(text.rstrip("\n"), "s.csv").ok.all()   # no end of line: 'ok' is whole, not torn
    f = tmp_path / "s.csv"
    f.write_text(text)
    assert main(["check", str(f)]) == 0
    assert "touches  3 (3 ok)" in capsys.readouterr().out
    # an OK row is a valid touch: its measured cells are required
    with pytest.raises(ProbeLogError, match=r"^s\.csv: row 0 \(line 3\): column 'X_mm' is empty$"):
        parse_probe_log(text.replace("1.0,10.0,0.0,0.0,10.0", "1.0,,0.0,0.0,10.0", 1), "s.csv")


POS = "# format: positioning-log/1\n{meta}target_mm,cycle,direction,measured_mm,status\n"


def positioning_text(word: str, meta: str = "") -> str:
    rows = [f"{t},{j},{d},{t + (0.001 if d == '+' else -0.001) + 0.0001 * j},{word}"
            for j in (1, 2) for d in "+-" for t in (0, 100)]
    return POS.format(meta=meta) + "\n".join(rows) + "\n"


def test_positioning_ok_in_any_case_and_no_valid_reading_names_the_words(tmp_path, capsys):
    """Spec (positioning-log.md): ``status`` (``ok`` or why the reading is not valid). review31 F6 (q/status_OK.csv):
    a log all ``OK`` got "no valid readings" with no hint. ``OK`` is ``ok``; a log whose words are all other
    words is refused naming them."""
    assert parse_positioning_log(positioning_text("OK"), "p.csv").ok.all()
    good = parse_positioning_log(positioning_text("good"), "p.csv")
    with pytest.raises(PositioningLogError, match=r"^p\.csv: no valid readings: every reading's status is not 'ok' "
                       r"\('good'\)$"):
        arrange(good)
    f = tmp_path / "p.csv"
    f.write_text(positioning_text("OK"))
    assert main(["iso230-2", str(f), "--json", str(tmp_path / "p.json")]) == 0
    capsys.readouterr()


# ---- F13: a metadata key given twice ---------------------------------------------------------------------------


def test_a_metadata_key_given_twice_with_two_values_is_refused(tmp_path, capsys):
    """Spec: lines before the header that begin with ``#`` are metadata, one ``# key: value`` per line.

    review31 F13 (p/meta_dup.csv: ``# stylus_r_mm: 2`` then ``# stylus_r_mm: 3``): the last line won without a
    word. A key with two values is refused naming it and both lines; the same value twice says one thing, kept.
    Positioning logs follow the same rule.
    """
    head = f"{HEAD}\nS1,T1,1.0,10.0,0.0,0.0,10.0,0.0,0.0,1,0,0\n"
    text = "# format: probe-log/1\n# stylus_r_mm: 2\n# stylus_r_mm: 3\n" + head
    with pytest.raises(ProbeLogError, match=r"^m\.csv: line 3: metadata key 'stylus_r_mm' given twice: '2' on line "
                       r"2, '3' on line 3: keep the one that holds$"):
        parse_probe_log(text, "m.csv")
    assert parse_probe_log(text.replace(": 3", ": 2"), "m.csv").meta["stylus_r_mm"] == "2"
    f = tmp_path / "m.csv"
    f.write_text(text)
    assert main(["check", str(f)]) == 2
    assert capsys.readouterr().err == (f"vmt check: error: {f}: line 3: metadata key 'stylus_r_mm' given twice: "
                                       "'2' on line 2, '3' on line 3: keep the one that holds\n")
    with pytest.raises(PositioningLogError, match=r"^p\.csv: line 3: metadata key 'axis' given twice: 'X' on line 2, "
                       r"'Y' on line 3"):
        parse_positioning_log(positioning_text("ok", "# axis: X\n# axis: Y\n"), "p.csv")
    assert parse_positioning_log(positioning_text("ok", "# axis: X\n# axis: X\n"), "p.csv").axis == "X"


# ---- F14: a '#' line after the header --------------------------------------------------------------------------


def test_a_comment_after_the_header_is_refused_saying_what_it_is(tmp_path, capsys):
    """Spec: lines *before the header* that begin with ``#`` are metadata; after it, one row per touch.

    review31 F14 (p/comment_after_header.csv, q/comment_body.csv): refused as "row 0 (line 3): 1 field, header
    has 12". Still refused, saying what the line is and where such lines go; the positioning log the same.
    """
    text = (f"# format: probe-log/1\n{HEAD}\n# a comment row\nS1,T1,1.0,10.0,0.0,0.0,10.0,0.0,0.0,1,0,0\n")
    msg = ("line 3: a '#' line after the header: metadata and comment lines are allowed only before the header "
           "(line 2); move it up or delete it")
    with pytest.raises(ProbeLogError) as e:
        parse_probe_log(text, "c.csv")
    assert str(e.value) == "c.csv: " + msg
    f = tmp_path / "c.csv"
    f.write_text(text)
    assert main(["check", str(f)]) == 2
    assert capsys.readouterr().err == f"vmt check: error: {f}: {msg}\n"
    pos = positioning_text("ok").splitlines()
    pos.insert(3, "# comment, with a comma")
    with pytest.raises(PositioningLogError) as e:
        parse_positioning_log("\n".join(pos) + "\n", "p.csv")
    assert str(e.value) == ("p.csv: line 4: a '#' line after the header: metadata and comment lines are allowed only "
                            "before the header (line 2); move it up or delete it")
    # a set-up whose name starts with '#' in a whole row is a row, not a comment
    assert parse_probe_log(text.replace("# a comment row\n", "").replace("\nS1,", "\n#1,"), "c.csv").columns[
        "setup"][0] == "#1"
