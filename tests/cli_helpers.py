"""Checks shared by the command-line tests."""


def one_line_error(capsys, *words):
    """The captured stderr: exactly one line, no traceback, holding each of ``words``; returned."""
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


class ProgressRecorder:
    """Stands in for :func:`scenarios.cli.guard.progress_line`'s bar: records every ``(done, total)`` a command
    draws (the real bar draws on a terminal only, so a test sees nothing of it)."""

    def __init__(self, label: str = ""):
        self.label, self.calls = label, []

    def __call__(self, done, total):
        self.calls.append((done, total))

    def begin(self, done, total):
        self(done, total)

    def clear(self):
        pass

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass


def record_progress(monkeypatch) -> list:
    """Every bar a command opens through ``progress_line`` from now on, in order (:class:`ProgressRecorder`)."""
    import scenarios.cli.guard as guard

    bars = []
    monkeypatch.setattr(guard, "progress_line", lambda label, **kw: bars.append(ProgressRecorder(label)) or bars[-1])
    return bars


def percent_counts(calls) -> list:
    """The ``done`` of a bar's calls in percent (``total`` 100), checked never to go back."""
    done = [d for d, t in calls if t == 100]
    assert done == sorted(done), done
    return done
