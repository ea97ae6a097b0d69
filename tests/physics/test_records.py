"""Named records across the compiled boundary, and the array namespaces (one per family, picklable by name)."""

from __future__ import annotations

import math
import pickle
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

from pneunet_env.config import EnvConfig
from pneunet_env.physics import solver
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.mechanics import Evaluation
from pneunet_env.physics.solver import DEFAULT_OPTIONS, Minimum, Solve, minimise_state, params_tuple, step_state
from pneunet_env.physics.xp import NUMPY, SCALAR, ops_named
from pneunet_env.task import EnvParams, Outcome, TaskState, Thresholds, Touch, make_rules

ROOT = Path(__file__).resolve().parents[2] / "pneunet_env"


def test_numba_builds_returns_and_reads_named_tuples():
    """What the records rely on: a compiled function builds a NamedTuple, reads it by name and returns it."""
    numba = pytest.importorskip("numba")

    class Pair(NamedTuple):
        low: float
        high: bool

    @numba.njit
    def build(x):
        p = Pair(x - 1.0, x > 0.0)
        return Pair(p.low * 2.0, p.high), p.low

    p, low = build(3.0)
    assert type(p) is Pair and p == (4.0, True) and low == 2.0


def test_the_compiled_solver_returns_records():
    r = step_state(0.0, 0.0, 0.0, 0.5, params_tuple(None), 1e-4, 0.02, DEFAULT_OPTIONS.as_tuple())
    assert type(r) is Solve and r.status <= 1 and r.kappa == r[0] and r.backtracks == r[-1] and r.evaluations > 0
    m = minimise_state((r.kappa, r.side_strain), 0.5, None, 1e-4, 0.02)
    assert type(m) is Minimum and m.kappa == pytest.approx(r.kappa, abs=1e-12)
    ev = solver.evaluate_state(r.kappa, r.side_strain, 0.5, params_tuple(None), 1e-4, 0.02)
    assert type(ev) is Evaluation and ev.ok and ev.volume_change == pytest.approx(r.volume_change, abs=1e-13)
    assert params_tuple(None).chamber_height == params_tuple(None)[0]


@pytest.mark.slow  # it compiles the solver's closures (seconds; the entries are cached on disk, they are not)
@pytest.mark.skipif(not HAVE_NUMBA, reason="needs numba")
def test_the_python_entries_return_the_compiled_records_field_for_field():
    """The entries Python calls (plain tuples across the boundary, records rebuilt in Python: see
    ``_jit.python_entry``) give exactly the records the compiled functions build, every field in its place."""
    prm, opts = params_tuple(None), DEFAULT_OPTIONS.as_tuple()
    for k, s, p0, p1, kobj in [(0.0, 0.0, 0.0, 0.5, 1e-4), (0.3, 0.01, 0.5, 0.9, 0.0), (0.2, 0.0, 0.4, 0.1, 1e-2)]:
        assert step_state(k, s, p0, p1, prm, kobj, 0.02, opts) == solver._follow_ev(k, s, p0, p1, prm, kobj, 0.02, opts)
        ev0 = solver._evaluate(k, s, p0, prm, kobj, 0.02)
        assert solver.evaluate_state(k, s, p0, prm, kobj, 0.02) == ev0
        r = solver.step_state_from(k, s, p0, p1, prm, kobj, 0.02, opts, ev0)
        assert r == solver._follow_from(k, s, p0, p1, prm, kobj, 0.02, opts, ev0) and type(r.evaluation) is Evaluation
        m = solver._minimise_entry(k, s, p1, prm, kobj, 0.02, opts[0], opts[1], opts[6])
        assert m == solver._minimise(k, s, p1, prm, kobj, 0.02, opts[0], opts[1], opts[6]) and type(m) is Minimum


@pytest.mark.skipif(not HAVE_NUMBA, reason="needs numba")
def test_the_compiled_rules_take_and_return_records():
    from pneunet_env import fused

    tp = EnvParams.from_config(EnvConfig()).task._replace(ops=None)
    out = fused._rules(TaskState(tp.squeeze_steps + tp.hold_steps - 1, False, False, 0.0), Touch(0.5, 0.1, True),
                       Thresholds(1.0, 1.0, 0.1), False, tp)
    assert type(out) is Outcome and type(out.state) is TaskState
    assert out.truncated and out.success and out.held and out.reward == tp.reward_hold + tp.reward_success
    assert out == make_rules(lambda f: 1.0 if f else 0.0, max)(
        TaskState(tp.squeeze_steps + tp.hold_steps - 1, False, False, 0.0), Touch(0.5, 0.1, True),
        Thresholds(1.0, 1.0, 0.1), False, tp)


def test_no_record_is_read_by_position():
    """The solver's, the kernel's and the actuator's records are read by name in the physics and the fused step."""
    positional = re.compile(r"\b(r|ev|evn|evc|raw|out|prm|kern)\[\d+\]")
    files = sorted((ROOT / "physics").glob("*.py")) + [ROOT / "fused.py"]
    hits = [f"{p.name}:{i}: {line.strip()}" for p in files for i, line in enumerate(p.read_text().splitlines(), 1)
            if positional.search(line)]
    assert not hits, hits


def test_namespaces_pickle_by_name():
    """A namespace (and so an env's params, which carry it) unpickles as this process's own object."""
    for ops in (SCALAR, NUMPY):
        assert pickle.loads(pickle.dumps(ops)) is ops
        assert ops_named(ops.name) is ops
    params = EnvParams.from_config(EnvConfig(), NUMPY)
    back = pickle.loads(pickle.dumps(params))
    assert back.ops is NUMPY and back == params and type(back.task) is type(params.task)
    torch = pytest.importorskip("torch")
    from pneunet_env.physics.xp import torch_ops

    ops = torch_ops("cpu")
    assert pickle.loads(pickle.dumps(ops)) is ops and ops.where(torch.tensor([True]), 1.0, 2.0).dtype == torch.float64
    with pytest.raises(ValueError, match="'jax'"):
        ops_named("jax")


def test_the_scalar_namespace_computes_as_the_one_env_did():
    """Python's numbers in, Python's numbers out; ``maximum``/``minimum`` are Python's (the first argument at a tie)."""
    assert SCALAR.where(True, 1.0, 2.0) == 1.0 and SCALAR.where(False, 1.0, 2.0) == 2.0
    assert SCALAR.maximum is max and SCALAR.minimum is min
    assert math.copysign(1.0, SCALAR.maximum(-0.0, 0.0)) == -1.0
    assert type(SCALAR.minimum(1.0, 2.0)) is float
    assert (SCALAR.full_like(None, 0, "int"), SCALAR.full_like(None, False, "bool")) == (0, False)
    assert type(SCALAR.full_like(None, 0, "int")) is int and type(SCALAR.full_like(None, 0.0, "float")) is float
    obs = SCALAR.to_float32(SCALAR.stack([0.5, 0.25]))
    assert obs.dtype == np.float32 and obs.tolist() == [0.5, 0.25]
