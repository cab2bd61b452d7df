"""One bounded cache for the module-level memos of vmt (least recently used out first).

Several modules keep answers that are pure functions of their inputs (a plan's
nominal design, a compiled scene, a collision check already made) so that a
study's runs, or the measurements of one plan, compute them once. Each of them
holds a :class:`Memo` with a stated ``maxsize``: when a new key would make it
larger, the entry used least recently goes (a hit, a look-up or a store counts
as a use; ``in`` does not). Memory is thereby bounded by ``maxsize`` entries.

What makes a memo safe is stated where it is declared, and is the caller's to
keep:

- the key holds everything the value depends on (a hash of arrays' bytes, the
  floats, the names), or the identity of an object whose value cannot change
  (a frozen artefact; :meth:`Memo.get_or_compute` with ``owner=obj`` keeps the
  object in the entry, so its ``id`` is not reused while the entry lives, and
  checks that the entry's object *is* ``obj``);
- a value handed to more than one caller is read-only (arrays with
  ``writeable = False``, frozen dataclasses, or by the callers' contract).

No locking: vmt runs these in one thread (parallel work is in processes, each
with its own memos).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Any

_MISSING = object()


def _same(kept: Any, owner: Any) -> bool:
    """``kept is owner``, item by item for two tuples of the same length."""
    if kept is owner:
        return True
    return (type(kept) is tuple and type(owner) is tuple and len(kept) == len(owner)
            and all(a is b for a, b in zip(kept, owner)))


class Memo:
    """A mapping of at most ``maxsize`` entries; the least recently used one is dropped first.

    Parameters
    ----------
    maxsize : int
        Largest number of entries kept, >= 1.

    Examples
    --------
    >>> m = Memo(2)
    >>> m["a"], m["b"] = 1, 2
    >>> m.get("a")          # "a" is now the most recently used
    1
    >>> m["c"] = 3          # drops "b", the least recently used
    >>> sorted(m.keys())
    ['a', 'c']
    """

    __slots__ = ("maxsize", "_d")

    def __init__(self, maxsize: int):
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise ValueError(f"Memo: maxsize must be an integer >= 1, got {maxsize!r}")
        self.maxsize = maxsize
        self._d: OrderedDict = OrderedDict()

    def get(self, key: Hashable, default: Any = None) -> Any:
        """The value kept for ``key`` (now the most recently used), else ``default``."""
        v = self._d.get(key, _MISSING)
        if v is _MISSING:
            return default
        self._d.move_to_end(key)
        return v

    def put(self, key: Hashable, value: Any) -> Any:
        """Keep ``value`` for ``key`` as the most recently used; drop the least recently
        used entry if there would be more than ``maxsize``. Returns ``value``."""
        d = self._d
        if key in d:
            d.move_to_end(key)
        elif len(d) >= self.maxsize:
            d.popitem(last=False)
        d[key] = value
        return value

    def get_or_compute(self, key: Hashable, compute: Callable[[], Any], owner: Any = None) -> Any:
        """The value kept for ``key``; on a miss ``compute()`` is called once and its answer kept.

        Parameters
        ----------
        key : hashable
            What the value depends on (see the module's notes).
        compute : callable () -> value
            Called on a miss only; its answer is kept and returned.
        owner : object, tuple of objects, or None
            For a key made of ``id(obj)`` (the value is a function of an object that
            cannot change): the entry keeps ``owner`` beside the value, so no other
            object can take its id while the entry lives, and the kept value is
            returned only if the entry's owner *is* ``owner`` (each item with ``is``
            for a tuple): an equal key from another object computes and replaces it.
            None: no owner (the entry is the bare value). A memo is used with owners
            at every call or at none.

        Returns
        -------
        The kept or computed value (``None`` and falsy values are kept like any other).
        """
        d = self._d  # (get and put inline: a hit, lambda included, ~0.1 us more than a hand-written look-up)
        if owner is None:
            v = d.get(key, _MISSING)
            if v is _MISSING:
                return self.put(key, compute())
            d.move_to_end(key)
            return v
        e = d.get(key)
        if e is not None:
            d.move_to_end(key)  # a use, as get's: also for an entry of another owner, replaced below
            if e[0] is owner or _same(e[0], owner):
                return e[1]
        return self.put(key, (owner, compute()))[1]

    def __getitem__(self, key: Hashable) -> Any:
        v = self.get(key, _MISSING)
        if v is _MISSING:
            raise KeyError(key)
        return v

    def __setitem__(self, key: Hashable, value: Any) -> None:
        self.put(key, value)

    def __contains__(self, key: Hashable) -> bool:
        return key in self._d

    def __len__(self) -> int:
        return len(self._d)

    def keys(self) -> list:
        """The keys, least recently used first."""
        return list(self._d)

    def clear(self) -> None:
        """Forget every entry."""
        self._d.clear()

    def __repr__(self) -> str:
        return f"Memo(maxsize={self.maxsize}, {len(self._d)} kept)"


def kept_on(obj: Any, name: str, compute: Callable[[], Any]) -> Any:
    """``compute()``, made once per object ``obj`` and kept on it (in its ``__dict__``, as
    :class:`functools.cached_property` keeps a property's value: a frozen dataclass allows it).

    For a value that is a pure function of an object that does not change (a
    campaign's :class:`core.baseline.PlanarData`), needed by more than one
    step while the object lives: unlike a :class:`Memo` at module level it
    goes with the object, so a long log's arrays are not kept alive after
    the run that needed them. ``name`` is the attribute it is kept under
    (choose one no field has); the value is shared by every caller, so it
    is read-only by the callers' contract (arrays: ``writeable = False``).

    >>> class D: pass
    >>> d, calls = D(), []
    >>> kept_on(d, "_x", lambda: calls.append(1) or 2), kept_on(d, "_x", lambda: calls.append(1) or 3), len(calls)
    (2, 2, 1)
    """
    kept = obj.__dict__
    v = kept.get(name, _MISSING)
    if v is _MISSING:
        v = kept[name] = compute()
    return v
