"""Session 23's early exits of :func:`core.discover._readings_only` answer as the set of labels did."""

from __future__ import annotations

from types import SimpleNamespace

from core.discover import _layout_label, _readings_only


def _by_labels(sc) -> bool:
    """The definition before session 23: every trial's label (less the reading) collected, then compared."""
    if sc.size == 1:
        return True
    labels = {tuple(sorted((k, v) for k, v in _layout_label(info).items() if k != "pretravel_along"))
              for info in sc.infos}
    return len(labels) == 1 and all("pretravel_along" in (info or {}) for info in sc.infos)


def _scan(*infos):
    return SimpleNamespace(infos=tuple(infos), size=len(infos))


def test_readings_only_answers_as_the_labels_did():
    two = ({"form": "k2", "pretravel_along": "normal", "w": 0.1}, {"form": "k2", "pretravel_along": "approach", "w": 0.2})
    cases = [
        _scan(),                                                   # no trial
        _scan({"degree": 2}),                                      # one trial
        _scan(None),                                               # one trial, no info
        _scan(*two),                                               # one layout in two readings: True
        _scan(two[0], {"form": "k4", "pretravel_along": "approach"}),  # two layouts, both with a reading
        _scan(two[0], {"form": "k2"}),                             # the second without the reading's key
        _scan({"form": "k2"}, {"form": "k2"}),                     # the same label, no reading
        _scan(two[0], None),                                       # a trial without info
        _scan(*two, {"form": "k2", "pretravel_along": "normal", "flag": True}),  # a bool is no label item
        _scan(*two, {"form": "k2", "pretravel_along": "normal", "n": 3}),       # an int is
        _scan(*({"centre_m": 0.01 * i, "axis": "x"} for i in range(50))),      # a path scan's many trials
    ]
    answers = [_readings_only(sc) for sc in cases]
    assert answers == [_by_labels(sc) for sc in cases]
    assert answers[3] and answers[8] and not answers[4] and not answers[5] and not answers[9]
