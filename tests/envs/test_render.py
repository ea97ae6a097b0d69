"""Rendering: frames are pictures of the state, PNGs round-trip, the render command writes them."""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401  (registers the environment)
from pneunet_env.envs.render import RenderState, contact_sheet, read_png, render_frame, save_png
from pneunet_env.physics.params import ActuatorParams


def _state(**kw) -> RenderState:
    base = dict(
        curvature=0.0, side_strain=0.0, params=ActuatorParams(), pressure_fraction=0.0, object_curvature=0.02,
        object_thickness=2.0, contact_force=0.0, indentation=0.0, in_contact=False, failure_traction=0.5,
        crush_indentation=2.0, grip_traction=2e-3, damaged=False, dropped=False, in_hold=False, progress=0.0,
        hold_start=0.5,
    )
    base.update(kw)
    return RenderState(**base)


def _reddish(img):
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (r > 170) & (g < 80) & (b < 80)


def test_frame_shape_dtype_and_size():
    f = render_frame(_state(), 200, 120)
    assert f.shape == (120, 200, 3) and f.dtype == np.uint8
    with pytest.raises(ValueError, match="32"):
        render_frame(_state(), 10, 10)


def test_frames_change_as_the_actuator_bends():
    flat = render_frame(_state())
    bent = render_frame(_state(curvature=0.3, side_strain=0.1, pressure_fraction=0.8))
    more = render_frame(_state(curvature=0.5, side_strain=0.2, pressure_fraction=1.0))
    assert np.mean(np.any(flat != bent, axis=-1)) > 0.05
    assert np.mean(np.any(bent != more, axis=-1)) > 0.02
    # a curled actuator reaches lower in the picture than a flat one (its ends curl down)
    def lowest_base_row(img):  # the dark PDMS base
        base = np.all(np.abs(img.astype(int) - [96, 104, 118]) < 12, axis=-1)[:, 40:-40]
        return np.nonzero(base.any(axis=1))[0].max()

    assert lowest_base_row(more) > lowest_base_row(flat) + 20


def test_damage_shows_in_red():
    kw = dict(curvature=0.0205, in_contact=True, indentation=1.0, contact_force=1e-3, pressure_fraction=0.5)
    ok = render_frame(_state(**kw))
    bad = render_frame(_state(damaged=True, **kw))
    assert _reddish(bad).sum() > _reddish(ok).sum() + 500


def test_indentation_is_drawn():
    # the object's material under the actuator shrinks as the indentation grows
    def object_pixels(delta):
        kappa = 1.0 / (50.0 - delta)
        img = render_frame(_state(curvature=kappa, in_contact=delta > 0, indentation=delta, contact_force=1e-3 * delta))
        r, g, b = (img[..., i].astype(int) for i in range(3))
        return ((r > 200) & (g > 150) & (b < 170) & (r - b > 50)).sum()

    assert object_pixels(0.0) > object_pixels(1.0) > object_pixels(1.8)


def test_render_modes_through_the_env(monkeypatch):
    env = gym.make("PneuNetGrasp-v0", render_mode="rgb_array", render_width=160, render_height=120,
                   terminate_on_damage=False)
    env.reset(seed=0, options={"object_stiffness": 1e-5})
    f0 = env.render()
    for _ in range(15):
        env.step(np.array([1.0]))
    f1 = env.render()
    assert f0.shape == f1.shape == (120, 160, 3) and f0.dtype == np.uint8
    assert not np.array_equal(f0, f1)
    env.close()
    pytest.importorskip("matplotlib")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    env = gym.make("PneuNetGrasp-v0", render_mode="human", render_width=160, render_height=120)
    env.reset(seed=0)
    env.step(np.array([1.0]))
    assert env.render() is None
    env.close()


def test_render_without_mode_warns_and_returns_none():
    env = gym.make("PneuNetGrasp-v0").unwrapped
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render"):
        assert env.render() is None


def test_png_round_trip_and_contact_sheet(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (17, 23, 3), dtype=np.uint8)
    path = save_png(tmp_path / "x.png", img)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert np.array_equal(read_png(path), img)
    sheet = contact_sheet([img] * 5, columns=2, gutter=3)
    assert sheet.shape == (3 * 17 + 4 * 3, 2 * 23 + 3 * 3, 3)
    assert np.array_equal(sheet[3:20, 3:26], img)
    with pytest.raises(ValueError):
        save_png(tmp_path / "y.png", img.astype(float))
    mpl_image = pytest.importorskip("matplotlib.image")
    assert np.array_equal((mpl_image.imread(path)[..., :3] * 255).round().astype(np.uint8), img)


def test_render_command_writes_frames_and_sheet(tmp_path):
    from pneunet_env.cli import render as cmd

    parser = argparse.ArgumentParser()
    cmd.add_arguments(parser)
    args = parser.parse_args(["--out", str(tmp_path), "--stiffness", "1e-5", "1e-2", "--steps", "6",
                              "--columns", "3", "--keep-going"])
    assert cmd.run(args) == 0
    frames = sorted((tmp_path / "frames").glob("*.png"))
    assert len(frames) == 2 * 7
    sheet = read_png(tmp_path / "sheet.png")
    f = read_png(frames[0])
    assert sheet.shape[0] > 2 * f.shape[0] and sheet.shape[1] > 3 * f.shape[1]
