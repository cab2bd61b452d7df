"""Malformed input of kinds no earlier test gave (audit37): one line naming the problem, exit 2, no
traceback, nothing written."""

import pytest

from scenarios.cli import main
from tests.cli_helpers import one_line_error


@pytest.fixture
def plan(tmp_path):
    p = tmp_path / "plan.csv"
    assert main(["plan", "grid", "--x-mm", "0:20:10", "--y-mm", "0:10:10", "--z-mm", "0", "--stylus-r-mm", "1.5",
                 "--out", str(p)]) == 0
    return p


@pytest.mark.parametrize("url", ["grbl://127.0.0.1:99999", "grbl://127.0.0.1:abc", "grbl://127.0.0.1:-1",
                                 "tcp://[::1:5000", "serial://[x"])
def test_probe_a_controller_url_urllib_cannot_read(plan, tmp_path, capsys, url):
    """A port out of 0-65535, a port that is not a number or a torn IPv6 bracket: urllib raises ValueError
    (`Port out of range 0-65535`, `Invalid IPv6 URL`), which reached the user as a 29-line traceback and
    exit 1 before audit37."""
    capsys.readouterr()
    out = tmp_path / "log.csv"
    assert main(["probe", "--controller", url, "--plan", str(plan), "--out", str(out),
                 "--limits-mm", "X-20:200,Y-20:200,Z-50:100", "--safe-z-mm", "50"]) == 2
    one_line_error(capsys, "vmt probe: error:", repr(url), "PORT a whole number 1-65535")
    assert not out.exists()


@pytest.mark.parametrize("url", ["virtual:nosuch", "virtual:simple"])
def test_probe_a_virtual_scene_it_does_not_have_names_its_own_option(plan, tmp_path, capsys, url):
    """`vmt probe --controller virtual:nosuch` answered in `vmt machine serve`'s words, `--scene 'nosuch':
    expected simple or one of ...`: an option probe does not have, and `simple`, which `virtual:simple`
    then refused the same way (probe's built-in scene is `virtual:`). Now the line names --controller."""
    capsys.readouterr()
    out = tmp_path / "log.csv"
    assert main(["probe", "--controller", url, "--plan", str(plan), "--out", str(out),
                 "--limits-mm", "X-20:200,Y-20:200,Z-50:100", "--safe-z-mm", "50"]) == 2
    err = one_line_error(capsys, "vmt probe: error: --controller", "virtual: (the built-in scene)", "cross-pocket")
    assert "--scene" not in err and "simple or" not in err
    assert not out.exists()


def test_bench_only_a_text_that_selects_no_benchmark(tmp_path, capsys):
    """`vmt bench --only nosuch` (a typo of a benchmark's name) ran nothing and wrote an empty figures
    document over --json, bench/results.json by default, exit 0. Now refused before anything runs: one line
    naming the text and the benchmarks, the --json file's bytes untouched."""
    out = tmp_path / "results.json"
    out.write_text('{"kept": true}\n')
    assert main(["bench", "--json", str(out), "--only", "bench_discovr"]) == 2
    one_line_error(capsys, "vmt bench: error: --only 'bench_discovr'", "bench_discover")
    assert out.read_text() == '{"kept": true}\n'


def test_an_allocation_beyond_memory_is_one_line_and_puts_the_outputs_back(tmp_path, capsys):
    """`vmt identify --mc 1000000000` (a few zeros too many) asks numpy for terabytes at once (581 GiB for 78 touches): a 26-line
    traceback of numpy's _ArrayMemoryError, exit 1, before audit37. Any command's MemoryError is now one line
    with numpy's words, exit 2, and the run's outputs are put back (an earlier --json kept byte for byte)."""
    log = tmp_path / "log.csv"
    assert main(["simulate", "cross-pocket", "--errors", "none", "--noise-um", "0.3", "--out", str(log)]) == 0
    out = tmp_path / "id.json"
    out.write_text("earlier\n")
    capsys.readouterr()
    assert main(["identify", str(log), "--json", str(out), "--mc", "1000000000"]) == 2
    one_line_error(capsys, "vmt identify: error: out of memory (Unable to allocate", "--mc")
    assert out.read_text() == "earlier\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["id.json", "log.csv"]
