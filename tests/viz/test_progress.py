"""viz.progress: drawn on a terminal only, with an estimate of the time left."""

import io

from viz.progress import TerminalProgress, format_duration, no_progress


class FakeTTY(io.StringIO):
    def isatty(self):
        return True


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_silent_when_not_a_terminal():
    s = io.StringIO()  # isatty() is False, like a pipe or a log file
    with TerminalProgress("campaign", stream=s) as p:
        for i in range(5):
            p(i + 1, 5)
    assert s.getvalue() == ""


def test_estimate_of_time_left_on_a_terminal():
    s, clock = FakeTTY(), Clock()
    p = TerminalProgress("Monte Carlo", stream=s, clock=clock, min_interval_s=0.0)
    clock.t = 10.0
    p(25, 100)  # 10 s for 25 -> 30 s left for 75 at the same mean rate
    assert "25/100" in s.getvalue() and "~30 s left" in s.getvalue()
    clock.t = 40.0
    p(100, 100)
    p.close()
    out = s.getvalue()
    assert out.endswith("done in 40 s\n") and out.count("\r") == 2


def test_a_resumed_run_estimates_from_its_own_items():
    """A campaign resumed with 60 of 100 touches on disk: after 10 s this run has done 5
    (2 s each), so 35 left take 70 s. Counting the 60 done before as done in those 10 s gave
    10 / 65 * 35 = 5 s (vmt probe --resume)."""
    s, clock = FakeTTY(), Clock()
    p = TerminalProgress("campaign", stream=s, clock=clock, min_interval_s=0.0)
    clock.t = 100.0  # connecting, recovering the log: not this run's touches
    p.begin(60, 100)
    assert p.done_before == 60  # a count of items, named as one (it was 'start', which reads as a time)
    assert s.getvalue().endswith("60/100 ( 60 %)")  # drawn at once, no estimate before a touch
    clock.t = 110.0
    p(65, 100)
    assert s.getvalue().endswith("65/100 ( 65 %)  ~1 min 10 s left")
    clock.t = 170.0
    p(100, 100)
    assert s.getvalue().endswith("done in 1 min 10 s")


def test_redraws_are_throttled_but_the_last_one_is_drawn():
    s, clock = FakeTTY(), Clock()
    p = TerminalProgress("hardware", stream=s, clock=clock, min_interval_s=1.0)
    for i in range(1, 100):
        clock.t = i * 0.01
        p(i, 100)
    p(100, 100)
    assert s.getvalue().count("\r") == 2  # the first update and the final one


def test_format_duration_and_null_callback():
    assert format_duration(42.4) == "42 s"
    assert format_duration(185) == "3 min 05 s"
    assert format_duration(7620) == "2 h 07 min"
    assert no_progress(1, 2) is None


def test_a_run_counted_in_the_last_runs_seconds_says_its_time_left_from_the_start():
    """vmt bench counts its benchmarks in the seconds they took last time: before the first one ends the time
    left is the last run's less the time spent (a single benchmark, --only X, said nothing until it ended);
    once one ends, the rate of this run (here twice as slow as the last)."""
    s, clock = FakeTTY(), Clock()
    p = TerminalProgress("bench", stream=s, clock=clock, min_interval_s=0.0, counts_seconds=True)
    p(0, 600)
    assert s.getvalue().endswith("0/600 (  0 %)  ~10 min 00 s left as the last run")
    clock.t = 30.0
    p(0, 600)
    assert s.getvalue().rstrip().endswith("~9 min 30 s left as the last run")    # (padded over the longer one)
    clock.t = 200.0
    p(100, 600)                         # 100 s of the last run's took 200 s: 500 more take 1000 s
    assert s.getvalue().rstrip().endswith("100/600 ( 17 %)  ~16 min 40 s left")
    q = TerminalProgress("campaign", stream=FakeTTY(), clock=Clock(), min_interval_s=0.0)
    assert q.line(0, 600).endswith("0/600 (  0 %)")           # a count of items: no estimate before one is done
