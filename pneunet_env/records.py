"""Operations on batched records (NamedTuples or dataclasses of ``(N,)`` arrays, nested): the arrays of a record,
a record's entries ``idx``, and a record with entries ``idx`` replaced, copied or written in place.

The vector env's autoreset (:func:`pneunet_env.task.autoreset`) is :func:`merge` of a fresh reset state into the
running one; the in-place form writes only into arrays that no state handed out earlier holds (:func:`fresh_arrays`).
"""

from __future__ import annotations

import dataclasses

from pneunet_env.physics.xp import NUMPY, Ops

__all__ = ["fresh_arrays", "leaves", "merge", "take"]


def _fields(record) -> tuple:
    if isinstance(record, tuple):
        return tuple(record)
    return tuple(getattr(record, f.name) for f in dataclasses.fields(record))


def leaves(record) -> list:
    """The arrays of a record (NamedTuple or dataclass, nested), in field order."""
    out = []
    for a in _fields(record):
        if isinstance(a, tuple) or dataclasses.is_dataclass(a):
            out.extend(leaves(a))
        else:
            out.append(a)
    return out


def merge(old, idx, new, ops: Ops = NUMPY, own: frozenset[int] | None = None):
    """A record (NamedTuple or dataclass, nested): ``old`` with entries ``idx`` replaced by ``new``'s.

    ``own=None``: every array (of the namespace ``ops``) is copied, never changed in place, so a state handed out
    earlier stays as it was. ``own``: the ids of ``old``'s arrays that nothing else holds (fresh this step, handed
    out to no one): those are written in place, the others copied first (the values are the same either way).
    """
    out = []
    for a, b in zip(_fields(old), _fields(new), strict=True):
        if isinstance(a, tuple) or dataclasses.is_dataclass(a):
            out.append(merge(a, idx, b, ops, own))
        else:
            c = a if own is not None and id(a) in own else ops.copy(a)
            c[idx] = b
            out.append(c)
    return type(old)(*out)


def take(record, idx):
    """The entries ``idx`` of every array of a record (NamedTuple or dataclass, nested): a record of fresh arrays."""
    return type(record)(*(take(a, idx) if isinstance(a, tuple) or dataclasses.is_dataclass(a) else a[idx]
                          for a in _fields(record)))


def fresh_arrays(state, earlier) -> frozenset[int]:
    """The ids of ``state``'s arrays that ``earlier`` (a state handed out before; ``None``: none was) does not hold,
    each held once in ``state``: what :func:`autoreset` may write in place."""
    held = set() if earlier is None else {id(a) for a in leaves(earlier)}
    seen: dict[int, int] = {}
    for a in leaves(state):
        seen[id(a)] = seen.get(id(a), 0) + 1
    return frozenset(i for i, count in seen.items() if count == 1 and i not in held)
