"""One random stream per sub-env, advanced as arrays: numpy's ``PCG64`` seeded through ``SeedSequence``.

:class:`PCG64Streams` holds N streams, each bit for bit numpy's ``Generator(PCG64(SeedSequence(seed_i)))`` (what a
single Gymnasium env's ``np_random`` is after ``reset(seed=seed_i)``), seeded and drawn with array operations (no
Python loop over the streams); :func:`seed_words` turns seeds into the words it is seeded from. The vector env
(:mod:`pneunet_env.envs.grasp_vector`) draws each sub-env's objects from its own stream.
"""

from __future__ import annotations

import operator
import sys
from collections.abc import Sequence

import numpy as np

from pneunet_env.physics import _jit

__all__ = ["PCG64Streams", "seed_words"]

_M32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_MASK32 = 0xFFFFFFFF
# numpy's SeedSequence (bit_generator.pyx): hash constants and a pool of 4 uint32 words.
_INIT_A, _MULT_A, _INIT_B, _MULT_B = 0x43B0D7E5, 0x931E8875, 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = 0xCA01F9DD, 0x4973F715
_POOL = 4
# PCG64 (pcg64.h): the 128-bit LCG multiplier, as two 64-bit halves.
_MULT_HI = np.uint64(2549297995355413924)
_MULT_LO = np.uint64(4865540595714422341)
_SEED_LIMIT = 1 << (32 * _POOL)


def _hashmix(value: np.ndarray, hc: int) -> tuple[np.ndarray, int]:
    value = value ^ np.uint32(hc)
    hc = (hc * _MULT_A) & _MASK32
    value = value * np.uint32(hc)
    return value ^ (value >> np.uint32(16)), hc


def _mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    r = np.uint32(_MIX_MULT_L) * x - np.uint32(_MIX_MULT_R) * y
    return r ^ (r >> np.uint32(16))


def _seed_sequence_words(words: np.ndarray) -> list[np.ndarray]:
    """``SeedSequence(seed).generate_state(8, uint32)`` for every column of ``words`` ((4, n) uint32: the seed's
    32-bit words, least significant first, zero-padded; numpy pads a short entropy the same way)."""
    hc = _INIT_A
    pool = []
    for i in range(_POOL):
        v, hc = _hashmix(words[i], hc)
        pool.append(v)
    for i_src in range(_POOL):
        for i_dst in range(_POOL):
            if i_src != i_dst:
                h, hc = _hashmix(pool[i_src], hc)
                pool[i_dst] = _mix(pool[i_dst], h)
    hc = _INIT_B
    out = []
    for i in range(2 * _POOL):
        v = pool[i % _POOL] ^ np.uint32(hc)
        hc = (hc * _MULT_B) & _MASK32
        v = v * np.uint32(hc)
        out.append(v ^ (v >> np.uint32(16)))
    return out


def _mulhi64(x: np.ndarray, y: np.uint64) -> np.ndarray:
    """The high 64 bits of the 128-bit product ``x * y`` (32-bit limbs)."""
    x0, x1 = x & _M32, x >> _S32
    y0, y1 = y & _M32, y >> _S32
    p00, p01, p10, p11 = x0 * y0, x0 * y1, x1 * y0, x1 * y1
    mid = (p00 >> _S32) + (p01 & _M32) + (p10 & _M32)
    return p11 + (p01 >> _S32) + (p10 >> _S32) + (mid >> _S32)


_U11, _U58, _U63, _U64 = (np.uint64(v) for v in (11, 58, 63, 64))


def _output(hi, lo):
    """PCG64's output of a state (XSL-RR) as a double in ``[0, 1)``: written for uint64 arrays and, compiled, for
    uint64 numbers alike (:data:`_draw` calls it)."""
    x = hi ^ lo
    rot = hi >> _U58
    u = (x >> rot) | (x << ((_U64 - rot) & _U63))
    return np.float64(u >> _U11) * (1.0 / 9007199254740992.0)


def _lcg_step(hi, lo, ihi, ilo):
    """``state * MULT + inc`` modulo 2**128, states as (high, low) uint64 halves."""
    nlo = lo * _MULT_LO
    nhi = _mulhi64(lo, _MULT_LO) + lo * _MULT_HI + hi * _MULT_LO
    lo2 = nlo + ilo
    return nhi + ihi + (lo2 < nlo).astype(np.uint64), lo2


class PCG64Streams:
    """N independent random streams, each numpy's ``Generator(PCG64(SeedSequence(seed_i)))``, drawn as arrays.

    Stream ``i`` seeded with ``seed_i`` yields exactly (bit for bit) the doubles of
    ``np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed_i))).random()``, which is what
    ``env.reset(seed=seed_i)`` gives a single Gymnasium env as ``env.np_random``. Seeding and drawing are
    array operations over the streams (numpy's SeedSequence hash and the 128-bit PCG64 LCG with its XSL-RR
    output, emulated with uint32/uint64 arithmetic), so there is no Python loop over envs.
    Each stream's state is 32 bytes.
    """

    def __init__(self, n: int) -> None:
        self.hi = np.zeros(n, np.uint64)
        self.lo = np.zeros(n, np.uint64)
        self.inc_hi = np.zeros(n, np.uint64)
        self.inc_lo = np.ones(n, np.uint64)

    @property
    def nbytes(self) -> int:
        return self.hi.nbytes + self.lo.nbytes + self.inc_hi.nbytes + self.inc_lo.nbytes

    def seed(self, idx: np.ndarray, words: np.ndarray) -> None:
        """Seed streams ``idx`` from their seeds' 32-bit words ``words`` ((4, len(idx)) uint32, least significant
        first): what ``PCG64(SeedSequence(seed))`` does."""
        with np.errstate(over="ignore"):
            st = _seed_sequence_words(words)
            v = [st[2 * k].astype(np.uint64) | (st[2 * k + 1].astype(np.uint64) << _S32) for k in range(4)]
            s_hi, s_lo, q_hi, q_lo = v
            # pcg_setseq_128_srandom_r: inc = (initseq << 1) | 1; state = 0; step; state += initstate; step.
            ihi = (q_hi << np.uint64(1)) | (q_lo >> np.uint64(63))
            ilo = (q_lo << np.uint64(1)) | np.uint64(1)
            hi, lo = _lcg_step(np.zeros_like(s_hi), np.zeros_like(s_lo), ihi, ilo)
            lo2 = lo + s_lo
            hi = hi + s_hi + (lo2 < lo).astype(np.uint64)
            hi, lo = _lcg_step(hi, lo2, ihi, ilo)
        self.hi[idx], self.lo[idx], self.inc_hi[idx], self.inc_lo[idx] = hi, lo, ihi, ilo

    def random(self, idx: np.ndarray, count: int) -> np.ndarray:
        """``count`` doubles in ``[0, 1)`` from each stream ``idx`` (distinct indices): shape ``(count, len(idx))``;
        advances them. With numba, one compiled pass (:data:`_draw`, the same integer arithmetic: the same doubles,
        bit for bit); without, array operations."""
        out = np.empty((count, len(idx)))
        if _draw is not None:
            _draw(self.hi, self.lo, self.inc_hi, self.inc_lo, np.asarray(idx, dtype=np.int64), out)
            return out
        hi, lo, ihi, ilo = self.hi[idx], self.lo[idx], self.inc_hi[idx], self.inc_lo[idx]
        with np.errstate(over="ignore"):
            for j in range(count):
                hi, lo = _lcg_step(hi, lo, ihi, ilo)
                out[j] = _output(hi, lo)
        self.hi[idx], self.lo[idx] = hi, lo
        return out

    def generator(self, i: int) -> np.random.Generator:
        """A ``np.random.Generator`` in the state of stream ``i`` (a copy: drawing from it does not advance ``i``)."""
        bg = np.random.PCG64()
        bg.state = {
            "bit_generator": "PCG64",
            "state": {"state": (int(self.hi[i]) << 64) | int(self.lo[i]),
                      "inc": (int(self.inc_hi[i]) << 64) | int(self.inc_lo[i])},
            "has_uint32": 0,
            "uinteger": 0,
        }
        return np.random.Generator(bg)


# the array forms' own functions, compiled: globals of the draw, not closure variables (numba keys its disk cache by
# the pickled closure, and a compiled function pickles differently in every process: the cache would never be hit)
_MULHI64_JIT, _OUTPUT_JIT = _jit.njit(_mulhi64), _jit.njit(_output)


def _make_draw(stamp: int):
    one, zero, mult_hi, mult_lo = np.uint64(1), np.uint64(0), _MULT_HI, _MULT_LO

    def draw(hi_a, lo_a, ihi_a, ilo_a, idx, out):
        # PCG64Streams.random, stream by stream: _lcg_step (its carry as a branch: numba types np.uint64(bool) as
        # int64, and int64 with uint64 gives float64) and _output, in uint64 (wrapping, as numpy's); writes out[j, c]
        # for stream idx[c] and advances it.
        if stamp < 0:  # the stamp keys the disk cache (see _jit.njit_cached)
            raise AssertionError
        for c in range(idx.shape[0]):
            i = idx[c]
            hi, lo, ihi, ilo = hi_a[i], lo_a[i], ihi_a[i], ilo_a[i]
            for j in range(out.shape[0]):
                nhi = _MULHI64_JIT(lo, mult_lo) + lo * mult_hi + hi * mult_lo
                nlo = lo * mult_lo
                lo = nlo + ilo
                hi = nhi + ihi + (one if lo < nlo else zero)
                out[j, c] = _OUTPUT_JIT(hi, lo)
            hi_a[i] = hi
            lo_a[i] = lo

    return draw


_draw = _jit.njit_cached(_make_draw, (sys.modules[__name__],)) if _jit.HAVE_NUMBA else None
"""The compiled draw (numba), or ``None``: then :meth:`PCG64Streams.random` uses array operations."""


def seed_words(seeds: Sequence[int] | int, n: int) -> np.ndarray:
    """The (4, n) uint32 words of the seeds ``seed + i`` (an int) or of a list of n ints; ``ValueError`` if invalid."""
    words = np.zeros((_POOL, n), np.uint32)
    if isinstance(seeds, (int, np.integer)) and not isinstance(seeds, (bool, np.bool_)):
        s = int(seeds)
        if s < 0 or s + n > _SEED_LIMIT:
            raise ValueError(f"seed must be an integer in [0, 2**128 - num_envs], got {seeds!r}")
        carry = np.arange(n, dtype=np.uint64)
        for j in range(_POOL):
            v = np.uint64((s >> (32 * j)) & _MASK32) + carry
            words[j] = (v & _M32).astype(np.uint32)
            carry = v >> _S32
        return words
    values = []
    for i, s in enumerate(seeds):  # a user's list of n seeds is converted once, at reset(seed=[...])
        try:
            v = operator.index(s)
        except TypeError:
            raise ValueError(f"seed[{i}] must be an integer, got {s!r}") from None
        if isinstance(s, (bool, np.bool_)) or v < 0 or v >= _SEED_LIMIT:
            raise ValueError(f"seed[{i}] must be an integer in [0, 2**128), got {s!r}")
        values.append(v)
    for j in range(_POOL):
        words[j] = np.array([(v >> (32 * j)) & _MASK32 for v in values], dtype=np.uint32)
    return words
