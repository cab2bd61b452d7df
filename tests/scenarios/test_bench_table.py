"""scenarios.bench: figures with their same-run references, and the README table generated from them (issue 19 item 8)."""

import json

import pytest

from core.exceptions import ConfigError
from scenarios.bench import document
from scenarios.bench.table import BEGIN, END, replace_table, table_markdown
from scenarios.cli import main

META = {"date_utc": "2026-12-02 01:00", "cpu_count": 2, "python": "3.11.7", "blas_threads": "1",
        "load_average_1min_at_start": 1.5, "load_average_1min_at_end": 2.0}


def small_doc():
    values = {"a_s": 3.0, "a_reference_s": 12.0, "b_per_s": 50, "zero_ref_s": 1.0, "z_s": 0.0,
              "count": 7, "broken_ratio_s": 2.0, "text_fig": "x|y"}
    refs = {"a_s": "a_reference_s", "zero_ref_s": "z_s", "broken_ratio_s": "missing_s", "text_fig": "a_s"}
    targets = {"a_s": "< 5 s", "b_per_s": "doubled"}
    origin = {k: "bench_one" for k in values}
    return document(META, values, refs, targets, origin)


def test_records_carry_reference_and_ratio():
    f = small_doc()["figures"]
    assert f["a_s"] == {"value": 3.0, "bench": "bench_one", "reference": "a_reference_s",
                        "reference_value": 12.0, "ratio": 0.25, "target": "< 5 s"}
    assert f["count"] == {"value": 7, "bench": "bench_one"}  # nothing declared: value only
    assert f["b_per_s"] == {"value": 50, "bench": "bench_one", "target": "doubled"}
    # no ratio rather than a wrong one: a zero, missing or non-numeric side
    assert f["zero_ref_s"]["ratio"] is None and f["zero_ref_s"]["reference_value"] == 0.0
    assert f["broken_ratio_s"]["ratio"] is None and f["broken_ratio_s"]["reference_value"] is None
    assert f["text_fig"]["ratio"] is None


def test_table_known_answer():
    t = table_markdown(small_doc()).splitlines()
    assert t[0].startswith("Measured 2026-12-02 01:00 UTC on 2 cores (load average 1.5 at the start, 2.0 at the end)")
    assert t[2] == "| figure | value | reference | reference value | ratio | target |"
    rows = t[4:]
    # the figures with a reference or a target, by module then name; "|" escaped
    assert rows == [
        "| `a_s` | 3 | `a_reference_s` | 12 | 0.25 | < 5 s |",
        "| `b_per_s` | 50 |  |  |  | doubled |",
        "| `broken_ratio_s` | 2 | `missing_s` |  |  |  |",
        "| `text_fig` | x\\|y | `a_s` | 3 |  |  |",
        "| `zero_ref_s` | 1 | `z_s` | 0 |  |  |",
    ]


def test_a_figure_its_run_could_not_measure_says_why_in_the_table():
    # the run wrote None and the reason beside it (probelog's discover under a memory limit)
    values = {"big_peak_mb": None, "big_s": None, "big_error": "exit 1 under a 6144 MB limit", "base_mb": 25.0,
              "lone_s": None}
    doc = document(META, values, {"big_peak_mb": "base_mb"}, {"big_peak_mb": "< 2048 MB", "lone_s": "< 1 s"},
                   {k: "bench_one" for k in values})
    rows = table_markdown(doc).splitlines()[4:]
    assert rows == ["| `big_peak_mb` | failed: see `big_error` | `base_mb` | 25 |  | < 2048 MB |",
                    "| `lone_s` | not measured |  |  |  | < 1 s |"]


def test_replace_table_touches_only_the_marked_section():
    readme = f"# title\n\ntext before\n\n{BEGIN}\nold table\nmore\n{END}\n\ntext after\n"
    out = replace_table(readme, "NEW\n")
    assert out == f"# title\n\ntext before\n\n{BEGIN}\nNEW\n{END}\n\ntext after\n"
    assert replace_table(out, "NEW\n") == out  # idempotent


@pytest.mark.parametrize("readme", ["no markers\n", f"{END}\n{BEGIN}\n", f"{BEGIN}\n{BEGIN}\n{END}\n"])
def test_replace_table_refuses_without_one_marked_section(readme):
    with pytest.raises(ConfigError, match="bench-table"):
        replace_table(readme, "T\n", "README.md")


def test_cli_regenerates_the_readme_from_a_json(tmp_path, capsys):
    res = tmp_path / "results.json"
    res.write_text(json.dumps(small_doc()))
    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{BEGIN}\n(run make bench)\n{END}\nrest\n")
    assert main(["bench", "--from-json", str(res), "--readme", str(readme)]) == 0
    text = readme.read_text()
    assert text.startswith(f"intro\n{BEGIN}\nMeasured ") and text.endswith(f"{END}\nrest\n")
    assert "| `a_s` | 3 | `a_reference_s` | 12 | 0.25 | < 5 s |" in text


@pytest.mark.parametrize("args, match", [
    (["--from-json", "{res}"], "--from-json only feeds --readme"),
    (["--from-json", "{tmp}/none.json", "--readme", "{readme}"], "none.json: no such file"),
    (["--from-json", "{bad}", "--readme", "{readme}"], "not a vmt bench document"),
])
def test_cli_bad_input_exit_2(tmp_path, capsys, args, match):
    res, bad, readme = tmp_path / "r.json", tmp_path / "bad.json", tmp_path / "README.md"
    res.write_text(json.dumps(small_doc()))
    bad.write_text(json.dumps({"a_s": 3.0}))  # the flat JSON of before: refused, not misread
    readme.write_text(f"{BEGIN}\n{END}\n")
    argv = [a.format(res=res, tmp=tmp_path, bad=bad, readme=readme) for a in args]
    assert main(["bench", *argv]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1
    assert readme.read_text() == f"{BEGIN}\n{END}\n"  # untouched


def _run(short, date, load, values, refs=None):
    meta = dict(META, date_utc=date, runs={short: {"date_utc": date, "invocation_utc": date,
                                                   "load_average_1min_at_start": load,
                                                   "load_average_1min_at_end": load + 1}})
    return document(meta, values, refs or {}, {}, dict.fromkeys(values, short))


def test_merge_replaces_only_the_benchmarks_run_again():
    from scenarios.bench import merge_documents

    old = merge_documents(_run("bench_one", "2026-12-02 01:00", 9.0, {"a_s": 3.0, "a_ref_s": 12.0, "gone_s": 1.0},
                               {"a_s": "a_ref_s"}),
                          _run("bench_two", "2026-12-02 01:30", 8.0, {"b_s": 5.0, "b_ref_s": 10.0},
                               {"b_s": "b_ref_s"}))
    new = _run("bench_one", "2026-12-02 05:00", 1.0, {"a_s": 2.0, "a_ref_s": 16.0}, {"a_s": "a_ref_s"})
    m = merge_documents(old, new)
    f = m["figures"]
    # bench_one's figures all come from the new run (its vanished figure goes); bench_two's stay
    assert set(f) == {"a_s", "a_ref_s", "b_s", "b_ref_s"}
    assert f["a_s"]["ratio"] == 0.125 and f["b_s"]["ratio"] == 0.5
    assert m["meta"]["runs"]["bench_one"]["date_utc"] == "2026-12-02 05:00"
    assert m["meta"]["runs"]["bench_two"]["load_average_1min_at_start"] == 8.0
    # the table says when each benchmark ran, since they did not run together
    head = table_markdown(m).splitlines()[0]
    assert "one 2026-12-02 05:00 (1.0/2.0); two 2026-12-02 01:30 (8.0/9.0)" in head


def test_cli_merge_keeps_what_was_not_run(tmp_path, monkeypatch):
    import scenarios.bench as B

    out = tmp_path / "results.json"
    out.write_text(json.dumps(_run("bench_two", "2026-12-02 01:30", 8.0, {"b_s": 5.0})))
    monkeypatch.setattr(B, "BENCHES", ["tests_bench_stub"])
    monkeypatch.setitem(__import__("sys").modules, "tests_bench_stub",
                        type("M", (), {"run": staticmethod(lambda: {"c_s": 1.5})}))
    assert main(["bench", "--json", str(out), "--merge"]) == 0
    f = json.loads(out.read_text())["figures"]
    assert f["b_s"]["value"] == 5.0 and f["c_s"]["value"] == 1.5
    assert set(json.loads(out.read_text())["meta"]["runs"]) == {"bench_two", "bench_tests_bench_stub"}


def test_one_invocation_keeps_the_one_line_heading():
    """Benchmarks of one `vmt bench` run start at different minutes: still one run, one heading."""
    doc = _run("bench_one", "2026-12-02 01:00", 1.0, {"a_s": 1.0})
    doc["meta"]["runs"]["bench_two"] = dict(doc["meta"]["runs"]["bench_one"], date_utc="2026-12-02 01:40")
    assert table_markdown(doc).startswith("Measured 2026-12-02 01:00 UTC on 2 cores")


def test_only_an_exact_name_selects_that_benchmark_alone():
    from scenarios.bench import BENCHES, _selects, short_name

    pick = lambda o: [short_name(b) for b in BENCHES if _selects(o, b, short_name(b))]  # noqa: E731
    assert pick("bench_discover") == ["bench_discover"]          # not bench_discover_study
    assert pick("discover") == ["bench_discover", "bench_discover_study"]
    assert pick("scenarios.bench.discover_study") == ["bench_discover_study"]


def _fake_benches(monkeypatch, names, broken=()):
    import sys
    import types

    import scenarios.bench as sb

    mods = []
    for name in names:
        m = types.ModuleType(f"fakebench_{name}")
        if name in broken:
            m.run = lambda: 1 / 0
        else:
            m.run = lambda name=name: {f"{name}_s": 1.0}
        monkeypatch.setitem(sys.modules, m.__name__, m)
        mods.append(m.__name__)
    monkeypatch.setattr(sb, "BENCHES", mods)
    return sb


def test_bench_progress_counts_the_last_runs_seconds(monkeypatch):
    """run_all reports progress before the first benchmark and after each (a broken one too), in the
    seconds each took in the last run (a new one: the median of the known), so the time left is not
    a mean over benchmarks of seconds and of half an hour; without a last run, in benchmarks."""
    sb = _fake_benches(monkeypatch, ["a", "b", "c"], broken=("b",))
    last = {"figures": {"bench_fakebench_a_wall_s": {"value": 100.0}, "bench_fakebench_b_wall_s": {"value": 10.2},
                        "bench_other_wall_s": {"value": 5.0}, "x_s": {"value": 3.0}}}
    expected = sb.expected_walls(last)
    assert expected == {"bench_fakebench_a": 100.0, "bench_fakebench_b": 10.2}
    calls = []
    doc = sb.run_all(progress=lambda d, t: calls.append((d, t)), expected=expected)
    assert calls == [(0, 210), (100, 210), (110, 210), (210, 210)]
    assert "bench_fakebench_b_error" in doc["figures"] and "c_s" in doc["figures"]
    calls.clear()
    sb.run_all(progress=lambda d, t: calls.append((d, t)))
    assert calls == [(0, 3), (1, 3), (2, 3), (3, 3)]
    calls.clear()
    sb.run_all(["fakebench_c"], progress=lambda d, t: calls.append((d, t)), expected=expected)
    assert calls == [(0, 100), (100, 100)]
    assert sb.expected_walls(None) == {} and sb.expected_walls({"figures": {"bench_fakebench_a_wall_s": 3}}) == {}


def test_vmt_bench_takes_the_time_left_from_its_out_file(monkeypatch, tmp_path):
    """vmt bench passes run_all a progress line and the walls of the --out file it is about to
    replace; with no such file, or one that is no bench document (replaced as before), none."""
    sb = _fake_benches(monkeypatch, ["a"])
    seen = []
    real = sb.run_all
    monkeypatch.setattr(sb, "run_all", lambda only=None, progress=None, expected=None:
                        seen.append((callable(progress), expected)) or real(only, progress, expected))
    import scenarios.cli.guard as guard

    lines, line = [], guard.progress_line       # the line counts the last run's seconds (session 38) when it has them
    monkeypatch.setattr(guard, "progress_line", lambda label, **kw: lines.append(kw) or line(label, **kw))
    out = tmp_path / "r.json"
    assert main(["bench", "--json", str(out)]) == 0
    assert seen[-1] == (True, {}) and lines[-1] == {"counts_seconds": False}
    out.write_text(json.dumps({"format": sb.FORMAT, "meta": {}, "figures": {
        "bench_fakebench_a_wall_s": {"value": 12.5, "bench": "bench_fakebench_a"}}}))
    assert main(["bench", "--json", str(out)]) == 0          # a last run's file
    assert seen[-1] == (True, {"bench_fakebench_a": 12.5}) and lines[-1] == {"counts_seconds": True}
    out.write_text("not json")
    assert main(["bench", "--json", str(out)]) == 0
    assert seen[-1] == (True, {}) and json.loads(out.read_text())["figures"]["a_s"]["value"] == 1.0


def test_a_broken_benchmark_fails_the_run_and_keeps_its_row(monkeypatch, tmp_path, capsys):
    """Session 38: `make bench` exited 0 with the MFB benchmark broken (KeyError) and README's table lost its five
    MFB rows without a word. The run now exits 1 naming it, and the table says it failed."""
    from scenarios.bench.table import BEGIN, END

    _fake_benches(monkeypatch, ["a", "b"], broken=("b",))
    readme = tmp_path / "README.md"
    readme.write_text(f"x\n{BEGIN}\nold\n{END}\n")
    out = tmp_path / "r.json"
    assert main(["bench", "--json", str(out), "--readme", str(readme)]) == 1
    err = capsys.readouterr().err
    assert "1 benchmark(s) failed" in err and "fakebench_b" in err
    table = readme.read_text()
    assert "| `bench_fakebench_b_error` | failed: ZeroDivisionError: division by zero |" in table
    _fake_benches(monkeypatch, ["a"])
    assert main(["bench", "--json", str(out), "--readme", str(readme)]) == 0
    assert "_error" not in readme.read_text()
