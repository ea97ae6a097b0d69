"""A signal handled while compiled code runs (a Ctrl-C's ``KeyboardInterrupt``) is raised as an exception, never a
segmentation fault, on every path by which Python calls the compiled solver.

numba builds a returned NamedTuple by running Python code, where a pending signal's handler runs first; if the
handler raises, numba calls NULL (numba issue #2324). ``pneunet_env.physics._jit.python_entry`` returns plain tuples
to Python instead. Found by ``tests/agents/test_interrupt.py`` (Ctrl-C during ``map``: exit status -11, 1 run in
about 35 to 150); here a timer raises in each path at random moments, about a thousand times a second, in a child
process (a crash must not take pytest with it). On the code before the fix the first path crashes within a second.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from pneunet_env.physics._jit import HAVE_NUMBA

pytestmark = [pytest.mark.slow, pytest.mark.skipif(not HAVE_NUMBA, reason="the crash is numba's")]

SECONDS_PER_PATH = 0.6
MIN_CAUGHT = 20
"""Interrupts each path must take (on a loaded machine it runs past SECONDS_PER_PATH, up to 30 s, to get them)."""

CHILD = textwrap.dedent('''
    import random, signal, sys, time
    import gymnasium as gym
    import numpy as np
    import pneunet_env
    from pneunet_env.envs.grasp_vector import PneuNetGraspVectorEnv
    from pneunet_env.physics import linear, solver

    class Tick(Exception):
        pass

    MIN_CAUGHT, CAP_S = int(sys.argv[2]), 30.0
    armed = running = False
    rng = random.Random(0)

    def handler(signum, frame):  # raises only inside the guarded call below, at most once per call
        global armed
        if running:
            signal.setitimer(signal.ITIMER_REAL, rng.uniform(5e-5, 2e-3))  # the next one, at a random moment
        if armed:
            armed = False
            raise Tick

    def single(env_id):
        env = gym.make(env_id)
        env.reset(seed=0)
        def call():
            if any(env.step(env.action_space.sample())[2:4]):
                env.reset()
        return call, env.reset

    def vector(**kw):
        env = PneuNetGraspVectorEnv(num_envs=16, **kw)
        env.reset(seed=0)
        act = np.full((16, 1), 0.5, np.float32)
        return (lambda: env.step(act)), (lambda: env.reset(seed=0))

    def solver_calls():
        eq = solver.solve_equilibrium(0.4, 1e-4, 0.02)
        def call():
            solver.solve_equilibrium(0.45, 1e-4, 0.02, initial=eq)
            solver.solve_equilibrium(0.45, 1e-4, 0.02, initial=(eq.curvature, eq.side_strain))
            solver.minimise_state((eq.curvature, eq.side_strain), 0.45, None, 1e-4, 0.02)
            linear.linear_error_estimate(eq.curvature, eq.side_strain, 0.4, 1e-4, 0.02, pneunet_env.ActuatorParams())
        return call, (lambda: None)

    paths = {
        "single env": lambda: single("PneuNetGrasp-v1"),
        "rigid env": lambda: single("RigidGrasp-v1"),
        "vector env, fused": lambda: vector(fused=True),
        "vector env, batched serial": lambda: vector(fused=False, parallel=False),
        "vector env, batched parallel": lambda: vector(fused=False, parallel=True),
        "solver API": solver_calls,
    }
    signal.signal(signal.SIGALRM, handler)
    for name, make in paths.items():
        call, recover = make()
        call()  # compiled before the timer starts
        caught = done = 0
        running = True
        signal.setitimer(signal.ITIMER_REAL, 1e-4)
        t0 = time.monotonic()
        # at least the given seconds, and on until the path was both interrupted and called to the end often enough
        # (a loaded machine makes fewer calls a second), within a cap
        while (time.monotonic() - t0 < float(sys.argv[1])
               or (caught <= MIN_CAUGHT or done == 0) and time.monotonic() - t0 < CAP_S):
            try:
                armed = True
                call()
                armed = False
                done += 1
            except Tick:
                caught += 1
                recover()
        running = False
        signal.setitimer(signal.ITIMER_REAL, 0)
        print(f"{name}: {done} calls, {caught} interrupted", flush=True)
''')


def test_signals_during_compiled_calls_raise_and_never_crash():
    proc = subprocess.run([sys.executable, "-X", "faulthandler", "-c", CHILD, str(SECONDS_PER_PATH), str(MIN_CAUGHT)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"exit status {proc.returncode}\n{proc.stdout}\n{proc.stderr[-3000:]}"
    lines = proc.stdout.splitlines()
    assert len(lines) == 6, proc.stdout
    for line in lines:  # every path was both called to the end and interrupted, many times
        done, caught = (int(w) for w in line.split(": ")[1].replace(" calls,", "").split()[:2])
        assert done > 0 and caught > MIN_CAUGHT, line
