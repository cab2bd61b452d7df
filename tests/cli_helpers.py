"""Checks shared by the command-line tests."""


def one_line_error(capsys, *words):
    """The captured stderr: exactly one line, no traceback, holding each of ``words``; returned."""
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err
