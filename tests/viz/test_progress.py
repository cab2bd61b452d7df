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
