"""core.memo.Memo: least-recently-used order, the size bound, get-or-compute, bad sizes."""

import pytest

from core.memo import Memo


def test_drops_the_least_recently_used_entry_first():
    m = Memo(3)
    m["a"], m["b"], m["c"] = 1, 2, 3
    assert m.get("a") == 1  # order of use now b, c, a
    m["d"] = 4  # drops b
    assert m.keys() == ["c", "a", "d"] and "b" not in m
    assert m["c"] == 3  # a look-up is a use: a, d, c
    m["e"] = 5  # drops a
    assert m.keys() == ["d", "c", "e"]
    m["d"] = 40  # storing an existing key is a use and does not evict
    assert m.keys() == ["c", "e", "d"] and m["d"] == 40 and len(m) == 3


def test_in_is_not_a_use():
    m = Memo(2)
    m["a"], m["b"] = 1, 2
    assert "a" in m
    m["c"] = 3
    assert m.keys() == ["b", "c"]


def test_never_more_than_maxsize():
    m = Memo(5)
    sizes = []
    for k in range(100):
        m[k % 17] = k
        sizes.append(len(m))
    assert max(sizes) == 5 and sizes[:5] == [1, 2, 3, 4, 5]
    assert m.keys() == [10, 11, 12, 13, 14]  # k = 95..99 stored last: 95 % 17 = 10 .. 99 % 17 = 14


def test_get_or_compute_calls_once_per_miss():
    calls = []
    m = Memo(2)

    def f(x):
        return lambda: calls.append(x) or x * 10

    assert m.get_or_compute(1, f(1)) == 10
    assert m.get_or_compute(1, f(1)) == 10
    assert calls == [1]
    m.get_or_compute(2, f(2)), m.get_or_compute(3, f(3))  # drops 1
    assert m.get_or_compute(1, f(1)) == 10 and calls == [1, 2, 3, 1]


def test_none_and_falsy_values_are_kept():
    calls = []
    m = Memo(4)
    for _ in range(3):
        assert m.get_or_compute("k", lambda: calls.append(1)) is None
    assert calls == [1] and m["k"] is None and m.get("k", "absent") is None
    assert m.get("missing", "absent") == "absent"
    with pytest.raises(KeyError):
        m["missing"]


def test_clear():
    m = Memo(3)
    m["a"] = 1
    m.clear()
    assert len(m) == 0 and "a" not in m


@pytest.mark.parametrize("bad", [0, -1, 2.5, True, None])
def test_bad_size(bad):
    with pytest.raises(ValueError, match="maxsize"):
        Memo(bad)
