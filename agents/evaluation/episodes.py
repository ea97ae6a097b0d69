"""One episode of a policy on an env, and its outcome (:func:`run_episode`); the seeds of a pinned grid's
episodes (:func:`episode_seed`).
"""

from __future__ import annotations

from typing import Any

__all__ = ["run_episode", "episode_seed"]


def run_episode(env, policy, seed: int | None = None, options: dict[str, Any] | None = None,
                record: bool = False) -> dict[str, Any]:
    """One episode of ``policy`` on ``env``; its outcome.

    ``policy.begin_episode(info)`` (if present) is called with ``reset``'s info. With ``record``, the
    command applied at each step (``pressure_kpa``, or ``jaw_closure_mm`` for the rigid gripper) is kept,
    from the reset state (index 0) to the last step.

    Returns:
        ``{stiffness, shear_modulus_kpa, success, damaged, dropped, return, steps, peak_traction_kpa,
        solver_failed, commands}`` (``commands`` only with ``record``).
    """
    obs, info = env.reset(seed=seed, options=options)
    reset_info = info  # the object's constants are in the reset info
    begin = getattr(policy, "begin_episode", None)
    if begin is not None:
        begin(info)
    key = "jaw_closure_mm" if "jaw_closure_mm" in info else "pressure_kpa"
    commands = [float(info[key])] if record else None
    ret, steps, peak, failed = 0.0, 0, 0.0, False
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        ret += reward
        steps += 1
        peak = max(peak, float(info["contact_force_kpa"]))
        failed = failed or bool(info.get("solver_failed", False))
        if record:
            commands.append(float(info[key]))
        if terminated or truncated:
            break
    out = {
        "stiffness": float(reset_info["object_stiffness"]),
        "shear_modulus_kpa": float(reset_info["object_shear_modulus_kpa"]),
        "curvature": float(reset_info["object_curvature"]),
        "object_class": str(reset_info.get("object_class", "ranges")),
        "success": bool(info.get("is_success", False)),
        "damaged": bool(info["damaged"]),
        "dropped": bool(info["dropped"]),
        "return": float(ret),
        "steps": steps,
        "peak_traction_kpa": peak,
        "solver_failed": failed,
    }
    if record:
        out["commands"] = commands
    return out


def episode_seed(seed: int, grid_index: int, episode: int) -> int:
    """The seed of episode ``episode`` at grid point ``grid_index`` (shared by every policy)."""
    return seed * 1_000_003 + 1000 * grid_index + episode
