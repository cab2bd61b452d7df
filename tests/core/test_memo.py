"""core.memo.Memo: least-recently-used order, the size bound, get-or-compute (with and without
an owner), bad sizes."""

import gc
import weakref
from functools import partial

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


def test_get_or_compute_hit_is_a_use():
    m = Memo(3)
    for k in "abc":
        m.get_or_compute(k, lambda k=k: k.upper())
    assert m.get_or_compute("a", lambda: "not called") == "A"  # order b, c, a
    m.get_or_compute("d", lambda: "D")  # drops b
    assert m.keys() == ["c", "a", "d"]


def test_none_and_falsy_values_are_kept():
    calls = []
    m = Memo(4)
    for _ in range(3):
        assert m.get_or_compute("k", lambda: calls.append(1)) is None
    assert calls == [1] and m["k"] is None and m.get("k", "absent") is None
    assert m.get("missing", "absent") == "absent"
    with pytest.raises(KeyError):
        m["missing"]


class _Art:
    """A stand-in for a frozen artefact (compared by identity only; weakref-able)."""


def test_owner_same_object_hits_other_object_with_equal_key_rebuilds():
    calls = []
    m = Memo(4)
    a, b = _Art(), _Art()

    def build(tag):
        return lambda: calls.append(tag) or [tag]  # a new list per call: identity tells which

    va = m.get_or_compute("k", build("a"), owner=a)
    assert m.get_or_compute("k", build("a again"), owner=a) is va and calls == ["a"]  # same object: kept
    vb = m.get_or_compute("k", build("b"), owner=b)  # equal key, another object: built and replaces a's
    assert vb == ["b"] and calls == ["a", "b"] and len(m) == 1
    assert m["k"][0] is b and m["k"][1] is vb  # the entry keeps its owner beside the value
    assert m.get_or_compute("k", build("a 3"), owner=a) == ["a 3"] and calls == ["a", "b", "a 3"]


def test_owner_tuple_checks_each_item():
    calls = []
    m = Memo(2)
    t, f, g = _Art(), ["x"], ["x"]  # f and g equal, not the same object

    def build():
        calls.append(1)
        return len(calls)

    assert m.get_or_compute("k", build, owner=(t, f)) == 1
    assert m.get_or_compute("k", build, owner=(t, f)) == 1  # a new tuple of the same objects: a hit
    assert m.get_or_compute("k", build, owner=(t, g)) == 2  # second item another object
    assert m.get_or_compute("k", build, owner=(t,)) == 3  # another length
    assert m.get_or_compute("k", build, owner=t) == 4  # not a tuple
    assert calls == [1, 1, 1, 1]


def test_owner_eviction_order_by_hand():
    # the sites' pattern: a look-up is a use, a miss stores as the most recently used, an
    # owner mismatch replaces the entry in place (stored again: most recently used, nothing dropped)
    m = Memo(3)
    arts = [_Art() for _ in range(5)]
    for i in range(3):
        m.get_or_compute(id(arts[i]), lambda i=i: i, owner=arts[i])
    k = [id(a) for a in arts]
    assert m.keys() == [k[0], k[1], k[2]]
    assert m.get_or_compute(k[0], lambda: "not called", owner=arts[0]) == 0  # hit: order 1, 2, 0
    assert m.keys() == [k[1], k[2], k[0]]
    assert m.get_or_compute(k[3], lambda: 3, owner=arts[3]) == 3  # drops 1
    assert m.keys() == [k[2], k[0], k[3]]
    assert m.get_or_compute(k[2], lambda: "2 again", owner=arts[4]) == "2 again"  # mismatch: no drop
    assert m.keys() == [k[0], k[3], k[2]] and len(m) == 3
    assert m.get_or_compute(k[1], lambda: "1 again", owner=arts[1]) == "1 again"  # 1 was dropped: drops 0
    assert m.keys() == [k[3], k[2], k[1]]


def test_compute_may_use_the_same_memo():
    # sim.mfb_scene._work_zone's pattern: building a zone looks up (and stores) its placement's
    # entry in the same memo; the zone is stored after it, as the most recently used
    m = Memo(3)
    a = _Art()
    m.get_or_compute("x", lambda: 0, owner=a)
    m.get_or_compute("y", lambda: 0, owner=a)

    def zone():
        return ("zone", m.get_or_compute("place", dict, owner=a))

    z = m.get_or_compute("zone", zone, owner=a)  # stores place (order x, y, place), then zone: drops x
    assert m.keys() == ["y", "place", "zone"] and z[1] is m["place"][1]
    assert m.get_or_compute("zone", zone, owner=a) is z


def test_owner_kept_alive_while_its_entry_lives():
    # the entry holds the owner, so its id cannot go to another object until the entry goes
    m = Memo(1)
    a = _Art()
    ref = weakref.ref(a)
    m.get_or_compute(id(a), lambda: 1, owner=a)
    del a
    gc.collect()
    assert ref() is not None
    m.get_or_compute("other", lambda: 2, owner=_Art())  # drops a's entry
    gc.collect()
    assert ref() is None


def test_compute_that_raises_keeps_nothing():
    m = Memo(2)
    m["a"] = 1

    def fail():
        raise RuntimeError("no")

    for owner in (None, _Art()):
        with pytest.raises(RuntimeError):
            m.get_or_compute("b", fail, owner=owner)
        assert m.keys() == ["a"]


def test_clear():
    m = Memo(3)
    m["a"] = 1
    m.clear()
    assert len(m) == 0 and "a" not in m


@pytest.mark.parametrize("bad", [0, -1, 2.5, True, None])
def test_bad_size(bad):
    with pytest.raises(ValueError, match="maxsize"):
        Memo(bad)


def test_kept_on_computes_once_per_object_and_goes_with_it():
    """core.memo.kept_on: one computation per object (a frozen dataclass included), kept on the object, not
    shared with another object, and gone with it (no module-level reference keeps the object alive)."""
    from dataclasses import dataclass

    from core.memo import kept_on

    @dataclass(frozen=True)
    class Data:
        v: int

    calls = []

    def make(d):
        calls.append(d.v)
        return [d.v * 2]

    a, b = Data(1), Data(1)
    first = kept_on(a, "_twice", partial(make, a))
    assert kept_on(a, "_twice", partial(make, a)) is first and first == [2] and calls == [1]
    assert kept_on(b, "_twice", partial(make, b)) is not first and calls == [1, 1]  # equal, but another object
    gone = weakref.ref(a)
    del a, first
    gc.collect()
    assert gone() is None
