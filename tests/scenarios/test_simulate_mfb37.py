"""`vmt simulate mfb` (the catalogue's bar: 17 placements, all along X, one stylus, no probe offsets J, no bar
certificate) writes a log `vmt identify` / `vmt discover` refuse (tests/scenarios/test_mfb_log_route.py): its help
and its own output say what the log is for and name `mfb-3axis` / `mfb-5axis`, whose logs they read (session 37:
a user following `vmt simulate --help` reached that refusal unwarned)."""

from core.probelog import read_probe_log
from scenarios.cli import main
from scenarios.cli.simulate import MFB_CATALOGUE_NOTE


def _help(capsys) -> str:
    import pytest

    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    return capsys.readouterr().out


def test_help_says_under_the_catalogues_mfb_what_its_log_is_for(capsys):
    text = _help(capsys)
    art = text.split("artefacts (and their defaults):", 1)[1]
    mfb = art.split("\n  cross-pocket", 1)[0]        # the mfb entry, up to the next artefact
    assert "default: on mikron-ucp710, 17 placements" in mfb
    said = " ".join(mfb.split())
    assert "refuse its log" in said and "mfb-3axis, mfb-5axis" in said and "along X" in said, mfb
    assert "\n  mfb-3axis " in art          # and the entry it points to is there


def test_the_catalogues_mfb_says_so_on_its_output_and_its_log_is_what_it_says(tmp_path, capsys):
    """The note is printed after the line naming the file, and what it says of the log holds: one stylus, no
    probe offsets or certificate lines (so `vmt discover` refuses it naming both); the note names the command
    that writes a log they read. Another artefact's output carries no such note."""
    from core.mfblog import BAR_E_KEY, STYLUS_COLUMN, STYLUS_OFFSETS_KEY, TOOL_OFFSET_KEY

    log = tmp_path / "m.csv"
    assert main(["simulate", "mfb", "--out", str(log)]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out[0].startswith(f"{log}: campaign of ") and out[-1] == MFB_CATALOGUE_NOTE
    assert "vmt simulate mfb-3axis" in MFB_CATALOGUE_NOTE and "refuse" in MFB_CATALOGUE_NOTE
    src = read_probe_log(log)
    assert not src.has(STYLUS_COLUMN)
    assert not {STYLUS_OFFSETS_KEY, TOOL_OFFSET_KEY, BAR_E_KEY} & set(src.meta)
    # (all its bars along X: given offsets and a certificate, identify refuses it "no bar lies along Y",
    # tests/scenarios/test_mfb_log_route.py::test_the_catalogs_mfb_log_is_refused_never_read_as_planar)
    res = tmp_path / "d.json"
    assert main(["discover", str(log), "--json", str(res)]) == 2
    err = capsys.readouterr().err
    assert "probe offsets J" in err and "the bar's calibration" in err and not res.exists()
    other = tmp_path / "c.csv"
    assert main(["simulate", "cross-pocket", "--out", str(other), "--c-angles-deg", "0"]) == 0
    assert MFB_CATALOGUE_NOTE not in capsys.readouterr().out
