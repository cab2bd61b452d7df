"""viz.report: a self-contained report folder, written atomically."""

import os

import pytest

from core.exceptions import ConfigError
from viz import figures as vf
from viz.report import Section, Table, write_report


def fig():
    return vf.rotary_centre_figure([0, 90, 180], [1.0, 2.0, 1.5], [0.0, 1.0, 0.5])


def test_report_folder_has_index_pngs_and_recording(tmp_path):
    rrd = tmp_path / "run.rrd"
    rrd.write_bytes(b"RRF2 fake recording")
    out = write_report(tmp_path / "report", "Cross pocket <4 C angles>", [
        Section("C axis", text="Centre trajectory.\n\nSecond paragraph & more.",
                figures={"C centre": fig()},
                tables=[Table(["symbol", "identified / µm", "U95 / µm"],
                              [["EX0C", 15.04321, 1.2], ["EY0C", 6.0, None]], caption="location")]),
        {"title": "Discovery", "figures": {"residuals": vf.residuals_figure([0, 1], [0, 90], [1, -1])},
         "tables": [{"columns": ["cause"], "rows": [["none"]]}]},
    ], recording=rrd)
    names = sorted(p.name for p in out.iterdir())
    assert names == ["C_centre.png", "index.html", "residuals.png", "run.rrd"]
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "<title>Cross pocket &lt;4 C angles&gt;</title>" in html  # escaped
    assert '<img src="C_centre.png"' in html and '<a href="run.rrd">' in html
    assert "vmt view run.rrd" in html
    assert "<td>15.04</td>" in html and "<th>U95 / µm</th>" in html
    assert "Second paragraph &amp; more." in html
    assert "http" not in html  # self-contained: nothing fetched from elsewhere
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp left
    assert (out / "C_centre.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_rewrite_replaces_the_old_report_whole(tmp_path):
    write_report(tmp_path / "r", "one", [Section("a", figures={"f1": fig()})])
    write_report(tmp_path / "r", "two", [Section("b", figures={"f2": fig()})])
    assert sorted(p.name for p in (tmp_path / "r").iterdir()) == ["f2.png", "index.html"]
    assert "two" in (tmp_path / "r" / "index.html").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


def test_failure_leaves_the_old_report_untouched(tmp_path):
    write_report(tmp_path / "r", "old", [])
    before = (tmp_path / "r" / "index.html").read_text()
    with pytest.raises(ConfigError, match="neither a matplotlib Figure nor an existing PNG"):
        write_report(tmp_path / "r", "new", [Section("a", figures={"x": 42})])
    assert (tmp_path / "r" / "index.html").read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


def test_png_path_is_copied(tmp_path):
    png = vf.save_png(fig(), tmp_path / "given.png")
    out = write_report(tmp_path / "r", "t", [Section("a", figures={"given": png})])
    assert (out / "given.png").read_bytes() == png.read_bytes()


@pytest.mark.parametrize("kwargs,match", [
    (dict(folder="nofolder/sub/r"), "parent folder does not exist"),
    (dict(recording="missing.rrd"), "no such file"),
    (dict(sections=lambda: [Section("a", figures={"f": fig(), "f ": fig()})]), "used twice"),
    (dict(sections=[42]), "expected Section or dict"),
])
def test_bad_input(tmp_path, kwargs, match):
    # figures are made here, not at collection (each xdist worker collects every file: a figure made in the
    # parameter list was made with pyplot on both workers, even the one that never runs this test)
    args = dict(folder=tmp_path / "r", title="t", sections=[])
    args.update({k: v() if callable(v) else v for k, v in kwargs.items()})
    if "recording" in kwargs:
        args["recording"] = tmp_path / kwargs["recording"]
    with pytest.raises(ConfigError, match=match):
        write_report(args.pop("folder"), args.pop("title"), args.pop("sections"), **args)
    assert not (tmp_path / "r").exists()


def test_table_checks_row_length_and_no_overwrite(tmp_path):
    with pytest.raises(ConfigError, match="table row 1: 1 cells for 2 columns"):
        Table(["a", "b"], [[1, 2], [3]])
    write_report(tmp_path / "r", "t", [])
    with pytest.raises(ConfigError, match="exists"):
        write_report(tmp_path / "r", "t", [], overwrite=False)
    umask = os.umask(0)
    os.umask(umask)
    # the folder gets the user's usual permissions, not mkdtemp's 0700
    assert os.stat(tmp_path / "r").st_mode & 0o777 == 0o777 & ~umask


def test_a_folder_of_other_files_or_the_working_folder_is_never_replaced(tmp_path, monkeypatch):
    """A report replaces its folder whole: main did so for any folder, so '--report results/' deleted
    the user's files in it (the old folder removed after the swap). Now only an earlier report
    (with index.html) or an empty folder is replaced."""
    mine = tmp_path / "results"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="holds 1 entry but no report of vmt"):
        write_report(mine, "x", [])
    assert (mine / "notes.txt").read_text() == "mine" and not (mine / "index.html").exists()
    (tmp_path / "empty").mkdir()
    assert (write_report(tmp_path / "empty", "x", []) / "index.html").is_file()
    write_report(tmp_path / "empty", "again", [])                       # an earlier report: replaced
    assert "again" in (tmp_path / "empty" / "index.html").read_text()
    monkeypatch.chdir(mine)
    with pytest.raises(ConfigError, match="working folder"):
        write_report(tmp_path, "x", [])
    assert (mine / "notes.txt").exists()


def test_only_a_report_vmt_wrote_holding_nothing_else_is_replaced(tmp_path):
    """main (b7ce9a1) took any folder with an index.html for an earlier report: a site/ of the user's
    (index.html, thesis.tex, img/) was replaced whole, and so was a report to which the user had added
    a file. Now index.html must name vmt as its generator and list the report's files, and the folder
    hold nothing else."""
    from viz.report import report_entries

    site = tmp_path / "site"
    (site / "img").mkdir(parents=True)
    (site / "index.html").write_text("<html><head><title>mine</title></head></html>\n")
    (site / "thesis.tex").write_text("precious")
    assert report_entries(site) is None
    with pytest.raises(ConfigError, match="holds 3 entries but no report of vmt"):
        write_report(site, "x", [])
    assert (site / "thesis.tex").read_text() == "precious" and (site / "img").is_dir()

    png = tmp_path / "given.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n")
    rrd = tmp_path / "my run.rrd"
    rrd.write_bytes(b"rrd")
    rep = write_report(tmp_path / "rep", 'a "title"', [Section("a", figures={"f 1": png})], recording=rrd)
    assert report_entries(rep) == ["index.html", "f_1.png", "my run.rrd"]          # as listed by hand
    (rep / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="is an earlier report but also holds notes.txt"):
        write_report(rep, "again", [])
    (rep / "notes.txt").unlink()
    (rep / "f_1.png").unlink()
    (rep / "f_1.png").mkdir()                           # a listed name that is now a folder: not the report's
    with pytest.raises(ConfigError, match="also holds f_1.png"):
        write_report(rep, "again", [])
    (rep / "f_1.png").rmdir()
    write_report(rep, "again", [])                      # an earlier report, less a figure: replaced
    assert sorted(p.name for p in rep.iterdir()) == ["index.html"]


def test_a_link_given_as_the_report_folder_is_refused(tmp_path, monkeypatch):
    """main replaced a link to an earlier report by a real folder and left the link, renamed
    '.lnk.XXXX.old', beside it (shutil.rmtree does not remove a link). Refused, all left as it was."""
    rep = write_report(tmp_path / "rep", "old", [])
    before = rep.joinpath("index.html").read_text()
    (tmp_path / "lnk").symlink_to("rep")
    (tmp_path / "dangling").symlink_to("nowhere")
    for link in ("lnk", "dangling"):
        with pytest.raises(ConfigError, match="is a symbolic link .* give the folder it points to"):
            write_report(tmp_path / link, "new", [])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dangling", "lnk", "rep"]
    assert (tmp_path / "lnk").is_symlink() and rep.joinpath("index.html").read_text() == before
