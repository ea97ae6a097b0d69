"""The torch backend agrees with the numba one: the masked solver on the solver study's scenes, and the vector env
through autoresets, folds and contact onset (torch on the CPU; the same code runs on a GPU).

Observations, rewards and flags must be equal and states agree within 1e-9. The one allowed exception is a flag
decided within 1e-9 of its threshold (the two back-ends' elementary functions differ in the last bits): such cases
are counted, listed in the output, and must be exactly that.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401  (registers the ids)
from pneunet_env.bench.solvers import make_scenes
from pneunet_env.physics._jit import HAVE_NUMBA
from pneunet_env.physics.batched import solve_batch

torch = pytest.importorskip("torch")

REFERENCE = "numba" if HAVE_NUMBA else "numpy"
TOL = 1e-9
DEVICES = ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(not torch.cuda.is_available(),
                                                                 reason="needs a CUDA GPU"))]
"""torch's devices: the CPU everywhere, and a GPU where there is one (CI has none; run on a GPU machine)."""


QUICK_SCENES = ()  # all run with the slow tests (the fold scene took 5 s of the quick loop; numpy runs the same
# masked solver in the quick tests, tests/physics/test_batched.py)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("scene", [
    sc if sc.name in QUICK_SCENES else pytest.param(sc, marks=pytest.mark.slow) for sc in make_scenes(quick=True)
], ids=lambda s: s.name)
def test_masked_torch_solver_follows_the_solver_study_scenes(scene, device):
    """Every scene (a snap-through fold, the Gent limit, big steps, the catalogue's stiffest corner ...), walked
    point by point: the torch answers equal the compiled ones (status, convergence, snaps; states to 1e-9)."""
    k = {b: np.zeros(1) for b in (REFERENCE, "torch")}
    s = {b: np.zeros(1) for b in (REFERENCE, "torch")}
    p0 = 0.0
    snaps = 0
    for p1 in scene.pressures:
        out = {}
        for b in (REFERENCE, "torch"):
            out[b] = solve_batch(k[b], s[b], p0, p1, scene.object_stiffness, scene.object_curvature, scene.params,
                                 backend=b, **({"device": device} if b == "torch" else {}))
            k[b] = _host(out[b].curvature)
            s[b] = _host(out[b].side_strain)
        ref, tor = out[REFERENCE], out["torch"]
        assert isinstance(tor.curvature, torch.Tensor) and tor.curvature.dtype == torch.float64
        assert tor.curvature.device.type == device
        assert int(tor.status[0]) == int(ref.status[0]), (scene.name, p1)
        assert bool(tor.converged[0]) == bool(ref.converged[0])
        assert bool(tor.snapped[0]) == bool(ref.snapped[0])
        assert abs(k["torch"][0] - k[REFERENCE][0]) <= TOL, (scene.name, p1)
        assert abs(s["torch"][0] - s[REFERENCE][0]) <= TOL, (scene.name, p1)
        if bool(ref.converged[0]):
            assert float(tor.gradient_norm[0]) <= 1e-10 and float(tor.min_eigenvalue[0]) > 0.0
        snaps += bool(ref.snapped[0])
        p0 = p1
    if scene.name in ("fold", "large steps"):
        assert snaps > 0, "the fold scenes must cross a snap-through"


def test_torch_solve_batch_validates_and_keeps_inactive_envs():
    k = torch.zeros(3, dtype=torch.float64)
    with pytest.raises(ValueError, match=r"p1\[1\]"):
        solve_batch(k, k, 0.0, torch.tensor([0.1, -1.0, 0.2]), backend="torch")
    with pytest.raises(ValueError, match="device"):
        solve_batch(k, k, 0.0, 0.1, backend="torch", device="no-such-device")
    with pytest.raises(ValueError, match="device"):
        solve_batch(np.zeros(3), np.zeros(3), 0.0, 0.1, backend="numpy", device="cpu")
    res = solve_batch(k + 0.1, k, 0.0, 0.5, backend="torch", active=torch.tensor([True, False, True]))
    assert int(res.status[1]) == -1 and float(res.curvature[1]) == 0.1 and bool(torch.isnan(res.energy[1]))
    assert bool(res.converged[0]) and bool(res.converged[2])


def _threshold_margin(info, i):
    """The relative distance of env ``i``'s state to the nearest of its damage/slip thresholds (full info)."""
    f, d = info["contact_force_kpa"][i], info["indentation_mm"][i]
    ratios = [f / info["failure_traction_kpa"][i], d / info["crush_indentation_mm"][i],
              f / info["grip_traction_kpa"][i] if info["grip_traction_kpa"][i] > 0 else np.inf]
    return min(abs(r - 1.0) for r in ratios)


def _host(x):
    return x.cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("env_id,mode,control", [
    pytest.param("PneuNetGrasp-v1", "SameStep", "jump", marks=pytest.mark.slow),  # 10 s: every param runs in CI
    pytest.param("PneuNetGrasp-v1", "NextStep", "jump", marks=pytest.mark.slow),
    pytest.param("PneuNetGrasp-Paper-v0", "SameStep", "jump", marks=pytest.mark.slow),
    pytest.param("PneuNetGrasp-v1", "SameStep", "branch", marks=pytest.mark.slow),
    pytest.param("PneuNetGrasp-Paper-v0", "SameStep", "branch", marks=pytest.mark.slow),
])
def test_torch_vector_env_agrees_with_numba_through_autoresets(env_id, mode, control, device):
    n, steps = 24, 60
    # the paper's ring keeps going when damaged, so that its grasps reach the fold
    kw = {"terminate_on_damage": False} if "Paper" in env_id else {}
    kw["step_control"] = control
    # the reference without the free table (numba's compiled step only): the same continuation as torch's
    ref = gym.make_vec(env_id, num_envs=n, backend=REFERENCE, info_level="full", autoreset_mode=mode, free_table=False,
                       **kw)
    # kernel=False: the masked solver round by round (on a CUDA device with numba-cuda the default is the kernel)
    tor = gym.make_vec(env_id, num_envs=n, backend="torch", device=device, info_level="full", autoreset_mode=mode,
                       kernel=False, **kw)
    # the paper's ring: the first episodes pinned across its snap-through window (k~ 5e-5 .. 1e-3)
    pins = {"object_stiffness": np.geomspace(5e-5, 1e-3, n)} if "Paper" in env_id else None
    o1, i1 = ref.reset(seed=11, options=pins)
    o2, i2 = tor.reset(seed=11, options=pins)
    assert isinstance(o2, torch.Tensor) and o2.dtype == torch.float32
    assert np.array_equal(o1, _host(o2)) and set(i1) == set(i2)
    rng = np.random.default_rng(5)
    near_threshold, ended, snapped, contact_onsets = [], 0, 0, 0
    was_in_contact = np.zeros(n, bool)
    for t in range(steps):
        # big steps (|a| up to 3, clipped), ramps and releases: folds, contact onset, damage, slip, autoresets
        a = (rng.uniform(-1.0, 3.0, (n, 1)) if t % 3 else rng.uniform(-3.0, 1.0, (n, 1))).astype(np.float32)
        r1 = ref.step(a)
        r2 = tor.step(torch.from_numpy(a).to(device))
        info1, info2 = r1[4], r2[4]
        flags_equal = [np.array_equal(r1[j], _host(r2[j])) for j in range(4)]
        if not all(flags_equal):
            for j in range(4):
                for i in np.flatnonzero(np.asarray(r1[j]).reshape(n, -1).any(1) != _host(r2[j]).reshape(n, -1).any(1)
                                        if j else (np.asarray(r1[j]) != _host(r2[j])).any(1)):
                    near_threshold.append((t, int(i), _threshold_margin(info1, i)))
        for key, v in info1.items():
            # (solver_evaluations: the work; numba's fused step takes the start's evaluation from its cache)
            if key in ("final_obs", "final_info", "solver_status", "solver_evaluations") or key.startswith("_"):
                continue
            w = _host(info2[key])
            if v.dtype == bool:
                bad = np.flatnonzero(v != w)
                near_threshold += [(t, int(i), _threshold_margin(info1, i)) for i in bad]
            else:
                assert np.allclose(np.asarray(v, float), w.astype(float), rtol=TOL, atol=TOL, equal_nan=True), key
        ended += int(np.sum(np.asarray(r1[2]) | np.asarray(r1[3])))
        snapped += int(np.sum(info1["snapped"]))
        contact_onsets += int(np.sum(info1["in_contact"] & ~was_in_contact))
        was_in_contact = np.asarray(info1["in_contact"]).copy()
    e1, e2 = ref.state.eq, tor.state.eq
    assert np.allclose(e1.curvature, _host(e2.curvature), rtol=0, atol=TOL)
    assert np.allclose(e1.side_strain, _host(e2.side_strain), rtol=0, atol=TOL)
    print(f"{env_id} {mode}: {ended} episode ends, {snapped} snaps, {contact_onsets} contact onsets, "
          f"{len(near_threshold)} flag(s) within 1e-9 of a threshold: {near_threshold}")
    assert ended >= n // 2, "the run must go through autoresets"
    assert contact_onsets > 0
    if "Paper" in env_id:
        assert snapped > 0, "the paper's ring must cross its snap-through fold"
    assert all(margin <= TOL for _, _, margin in near_threshold), near_threshold


def test_torch_vector_env_seeding_and_arguments():
    a = gym.make_vec("PneuNetGrasp-v1", num_envs=4, backend="torch")
    b = gym.make_vec("PneuNetGrasp-v1", num_envs=4, backend="numpy")
    _, ia = a.reset(seed=[3, 4, 5, 6])
    _, ib = b.reset(seed=[3, 4, 5, 6])
    assert np.array_equal(_host(ia["object_stiffness"]), ib["object_stiffness"])
    assert a.state_nbytes() > 0 and a.device == torch.device("cpu")
    with pytest.raises(ValueError, match="device"):
        gym.make_vec("PneuNetGrasp-v1", num_envs=2, backend="numpy", device="cpu")
    with pytest.raises(ValueError, match="device"):
        gym.make_vec("PneuNetGrasp-v1", num_envs=2, backend="torch", device="nowhere")
    with pytest.raises(ValueError, match=r"actions\[1\]"):
        a.step(torch.tensor([[0.1], [float("nan")], [0.0], [0.0]]))
    with pytest.raises(ValueError, match="shape"):
        a.step(torch.zeros(3, 1))
    with pytest.raises(TypeError, match="dtype"):
        a.step(torch.zeros(4, 1, dtype=torch.bool))
    obs, *_ = a.step(np.zeros((4, 1)))  # numpy actions are accepted too
    assert isinstance(obs, torch.Tensor)


def test_torch_vector_env_renders_and_reports_objects():
    env = gym.make_vec("PneuNetGrasp-v1", num_envs=2, backend="torch", render_mode="rgb_array")
    env.reset(seed=0)
    env.step(torch.ones(2, 1))
    frames = env.render()
    assert len(frames) == 2 and frames[0].shape[2] == 3 and frames[0].dtype == np.uint8
    assert isinstance(env.unwrapped.objects.stiffness, torch.Tensor)
    assert isinstance(env.unwrapped.equilibrium(1).curvature, float)


@pytest.mark.slow  # a few seconds: the quick loop stays under a minute
def test_the_gpu_form_of_the_masked_solver_equals_the_cpu_form():
    """What ``torch.compile``'s round runs on a GPU (every env through every round, a check every 8 rounds), and
    compaction checked at another cadence, give the CPU form's answers on the CPU: the
    same path (iterations, sub-steps, snaps, status) and the same states to the last bits (an AVX2 machine rounds one
    env's side strain 1 ulp apart: the arrays' lengths differ, and with them torch's vectorised tails); and a round
    budget flags the envs it cuts short (STATUS_BUDGET, unconverged), never hangs."""
    from pneunet_env.physics import masked
    from pneunet_env.physics.solver import DEFAULT_OPTIONS, STATUS_BUDGET, params_tuple
    from pneunet_env.physics.xp import torch_ops

    rng = np.random.default_rng(3)
    n = 300
    t = lambda a: torch.tensor(a, dtype=torch.float64)  # noqa: E731
    k, s = t(np.zeros(n)), t(np.zeros(n))
    p1 = t(rng.uniform(0.0, 1.2, n))
    kobj, ko = t(10 ** rng.uniform(-5, 1.6, n)), t(rng.uniform(0.02, 0.5, n))
    active = torch.tensor(rng.random(n) < 0.95)
    ops, prm, opts = torch_ops("cpu"), params_tuple(None), DEFAULT_OPTIONS.as_tuple()
    cpu = masked.solve_masked(k, s, k * 0, p1, kobj, ko, prm, opts, active, ops, compact=True)
    for compact, every in ((False, 8), (True, 3)):  # the compiled round's schedule, and compaction at another cadence
        gpu = masked.solve_masked(k, s, k * 0, p1, kobj, ko, prm, opts, active, ops, compact=compact,
                                  check_every=every)
        for name in masked.OUTPUTS:
            a, b = torch.nan_to_num(cpu[name].double(), nan=-7.0), torch.nan_to_num(gpu[name].double(), nan=-7.0)
            if name in ("iterations", "substeps", "snapped", "status"):  # the path taken: the same, exactly
                assert torch.equal(a, b), name
            else:  # compaction changes the vector lengths: torch's SIMD tails (CPU-dependent) may round the last bit
                assert torch.allclose(a, b, rtol=1e-13, atol=1e-13), (name, float((a - b).abs().max()))
    cut = masked.solve_masked(k, s, k * 0, p1, kobj, ko, prm, opts, active, ops, compact=False, check_every=8,
                              max_rounds=5)
    flagged = cut["status"] == STATUS_BUDGET
    assert bool(flagged.any()) and not bool((flagged & ~active).any())
    assert bool(torch.isfinite(cut["kappa"]).all())
