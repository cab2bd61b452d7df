"""Every JSON vmt writes names its format in a top-level ``format`` key (docs/formats.md), and the
readers that read vmt's JSON back accept it. The costly writers are checked where their outputs are
already made: the demo (identify, discover, MFB, closed loop, the demo's ISO 230-2 file) in
test_demo.py, the paper scenarios in test_paper_scenarios.py, identify (read back as a machine state)
and design in test_identify_cli.py, iso230-2 in test_iso230_2_cli.py; the regression study reads
discover's JSON back in test_regress.py."""

import json

import pytest

from core.exceptions import ConfigError
from scenarios.cli import main


def _circle_log(path):
    """Eight touches of a 20 mm bore (tip centres on 17 mm, stylus 3 mm): a log fit and check read."""
    import numpy as np

    from core.probelog import make_log, write_probe_log

    a = np.arange(8) * np.pi / 4
    c, s = np.cos(a), np.sin(a)
    n = a.size
    cols = {"setup": ["S1"] * n, "target": [f"b{k}" for k in range(n)], "t_s": np.arange(n, dtype=float),
            "X_mm": 7.0 * c, "Y_mm": 7.0 * s, "Z_mm": np.full(n, -5.0), "Xn_mm": 7.0 * c, "Yn_mm": 7.0 * s,
            "Zn_mm": np.full(n, -5.0), "nx": -c, "ny": -s, "nz": np.zeros(n), "feature": ["bore"] * n,
            "stylus_r_mm": np.full(n, 3.0)}
    return write_probe_log(path, make_log(cols, {"artefact": "bore"}))


def test_check_and_fit_name_their_format(tmp_path, capsys):
    log = _circle_log(tmp_path / "bore.csv")
    assert main(["check", str(log), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["format"] == "vmt-check/1"
    assert main(["fit", "circle", str(log), "--json", str(tmp_path / "fit.json")]) == 0
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert fit["format"] == "vmt-fit/1" and fit["values"]["radius_mm"] == pytest.approx(10.0, abs=1e-9)


def test_bench_documents_name_their_format_and_the_table_refuses_another():
    from scenarios.bench import FORMAT, document, merge_documents
    from scenarios.bench.table import table_markdown

    a = document({"runs": {"bench_a": {"date_utc": "d"}}}, {"x_s": 1.0, "r_s": 2.0}, {"x_s": "r_s"}, {},
                 {"x_s": "bench_a", "r_s": "bench_a"})
    assert a["format"] == FORMAT == "vmt-bench/1"
    old = {k: v for k, v in a.items() if k != "format"}          # a results.json written before the key
    assert merge_documents(old, a)["format"] == FORMAT
    assert "`x_s`" in table_markdown(a) and "`x_s`" in table_markdown(old)
    with pytest.raises(ConfigError, match=r"bench results: format 'vmt-identify/1', expected 'vmt-bench/1'"):
        table_markdown(dict(a, format="vmt-identify/1"))
