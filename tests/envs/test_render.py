"""Rendering: frames are pictures of the state, PNGs round-trip, the render command writes them."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import pneunet_env  # noqa: F401  (registers the environment)
from pneunet_env.envs.render import (
    FONT_HEIGHT,
    FONT_WIDTH,
    LABEL_MIN_HEIGHT,
    LABEL_MIN_WIDTH,
    LEGEND,
    RenderState,
    contact_sheet,
    frame_status,
    label_lines,
    legend_strip,
    read_png,
    render_frame,
    save_png,
    text_mask,
)
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


# Reference frames (tests/envs/data/render_reference/): states reached in the env, stored (states.json) with the
# frames drawn of them (NAME.png), so that the test compares the renderer alone, whatever the env's physics or
# defaults become. The cases: (name, reset options, steps of action +1 from reset (seed 0), frame size).
# The stored frames were drawn by the numpy rasteriser as it was before it was made fast (pixel masks over the
# whole supersampled canvas), and are the scene without the text label (``label=False``; the label, drawn over the
# scene after it, is tested on its own below); ``python tests/envs/test_render.py`` rewrites them with today's
# renderer: only when the picture is meant to change.
REFERENCE_DIR = Path(__file__).parent / "data" / "render_reference"
_WIDE = {"object_curvature": 0.02}  # a wide object: a shallow arc across the frame
REFERENCE_CASES = (
    ("rest", {"object_stiffness": 1e-4}, 0, (480, 360)),  # flat, out of contact
    ("ring_contact", {"object_stiffness": 1e-2}, 15, (480, 360)),  # curled round a small ring
    ("ring_held", {"object_stiffness": 1e-2}, 55, (480, 360)),  # held, in the hold phase
    ("soft_loaded", {"object_stiffness": 1e-5, **_WIDE}, 4, (480, 360)),  # indented, the loaded zone tinted
    ("soft_damaged", {"object_stiffness": 1e-5, **_WIDE}, 10, (480, 360)),  # crushed through: damaged, a film
    ("soft_dropped", {"object_stiffness": 1e-5, **_WIDE}, 55, (480, 360)),  # damaged and dropped in the hold
    ("firm_loaded", {"object_stiffness": 1e-3, **_WIDE}, 8, (480, 360)),
    # indented past H (6.4 w > H = 0.76 w), not crushed (hoop strain: below 28 w): no film
    ("firm_deep", {"object_stiffness": 1e-3, **_WIDE}, 20, (480, 360)),
    ("small", {"object_stiffness": 1e-3, **_WIDE}, 15, (160, 120)),
)


def _env_state(options: dict, steps: int, size: tuple[int, int]):
    """The env's render state and render config after ``steps`` steps of ``+1`` (damage and slip don't end it)."""
    env = gym.make("PneuNetGrasp-v1", render_mode="rgb_array", render_width=size[0], render_height=size[1],
                   terminate_on_damage=False, terminate_on_slip=False)
    env.reset(seed=0, options=options)
    for _ in range(steps):
        env.step(np.array([1.0], np.float32))
    state, cfg = env.unwrapped.render_state(), env.unwrapped.config.render
    env.close()
    return state, {"width": cfg.width, "height": cfg.height, "chambers": cfg.chambers}


def _state_json(state: RenderState) -> dict:
    d = state._asdict()
    d["params"] = dataclasses.asdict(state.params)
    return d


def _state_from_json(d: dict) -> RenderState:
    return RenderState(**{**d, "params": ActuatorParams(**d["params"])})


def _write_reference_frames(render=render_frame) -> None:
    REFERENCE_DIR.mkdir(parents=True, exist_ok=True)
    cases = []
    for name, options, steps, size in REFERENCE_CASES:
        state, frame = _env_state(options, steps, size)
        cases.append({"name": name, "options": options, "steps": steps, "frame": frame, "state": _state_json(state)})
        path = save_png(REFERENCE_DIR / f"{name}.png", render(state, **frame, label=False))
        print(f"{path}: {path.stat().st_size} bytes")
    (REFERENCE_DIR / "states.json").write_text(json.dumps(cases, indent=1) + "\n")


def _reference_cases() -> list[dict]:
    return json.loads((REFERENCE_DIR / "states.json").read_text())


def _reddish(img):
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (r > 170) & (g < 80) & (b < 80)


def test_frame_shape_dtype_and_size():
    f = render_frame(_state(), 200, 120)
    assert f.shape == (120, 200, 3) and f.dtype == np.uint8
    with pytest.raises(ValueError, match="32"):
        render_frame(_state(), 10, 10)
    # odd sizes and other supersamplings (an odd subpixel grid is drawn whole, not as a mirrored half)
    kw = dict(curvature=0.3, in_contact=True, indentation=0.5, contact_force=1e-3, pressure_fraction=0.7)
    for width, height, chambers, ss in ((161, 121, 7, 2), (99, 64, 3, 1), (97, 65, 12, 3)):
        f = render_frame(_state(**kw), width, height, chambers=chambers, supersample=ss)
        assert f.shape == (height, width, 3) and f.dtype == np.uint8 and f.flags.c_contiguous
        assert np.array_equal(f, render_frame(_state(**kw), width, height, chambers=chambers, supersample=ss))


# Tolerance of the comparison with the reference frames: the mean absolute difference (over every channel of
# every pixel, in grey levels) and the fraction of pixels with a channel off by more than 16 levels.
REFERENCE_MEAN_ABS_MAX = 0.25
REFERENCE_FRACTION_OFF_16_MAX = 1e-3


def test_frames_match_the_reference_frames():
    """The picture is the one drawn before the renderer was made fast (the frames under ``data/render_reference``).

    It is drawn the same way (2 x 2 supersampling, the same shapes and outlines, averaged in the same order), so
    frames match to rounding: only a pixel here and there of the loaded zone's tint (computed at the pixel's
    centre, not averaged over its subpixels) may be off, by a grey level. The references are the scene alone: the
    text label is left out (``label=False``), and is tested by the tests of the label.
    """
    cases = _reference_cases()
    assert [c["name"] for c in cases] == [c[0] for c in REFERENCE_CASES]
    for case in cases:
        ref = read_png(REFERENCE_DIR / f"{case['name']}.png")
        got = render_frame(_state_from_json(case["state"]), **case["frame"], label=False)
        assert got.shape == ref.shape == (case["frame"]["height"], case["frame"]["width"], 3), case["name"]
        diff = np.abs(got.astype(int) - ref.astype(int))
        off_16 = np.mean(diff.max(axis=-1) > 16)
        assert diff.mean() <= REFERENCE_MEAN_ABS_MAX and off_16 <= REFERENCE_FRACTION_OFF_16_MAX, (
            f"{case['name']}: mean |difference| {diff.mean():.4f} grey levels, {off_16:.2%} of the pixels off by "
            "> 16 (if the picture is meant to change, rewrite the references: python tests/envs/test_render.py)"
        )


def test_the_env_renders_what_render_frame_draws_of_its_state():
    state, frame = _env_state({"object_stiffness": 1e-4}, 5, (160, 120))
    env = gym.make("PneuNetGrasp-v1", render_mode="rgb_array", render_width=160, render_height=120,
                   terminate_on_damage=False, terminate_on_slip=False)
    env.reset(seed=0, options={"object_stiffness": 1e-4})
    for _ in range(5):
        env.step(np.array([1.0], np.float32))
    assert np.array_equal(env.render(), render_frame(state, **frame))
    env.close()


def test_render_benchmark_runs():
    from pneunet_env.bench.render_speed import bench_render

    r = bench_render(frames=3, repeats=1)
    assert r["pneunet_frames_per_s"] > 0 and r["pneunet_frame_shape"] == [360, 480, 3]
    if r["cartpole_frames_per_s"] is None:  # CartPole-v1 draws with pygame, which this package does not need
        assert r["cartpole_error"] and r["ratio"] is None
    else:
        assert r["ratio"] == pytest.approx(r["pneunet_frames_per_s"] / r["cartpole_frames_per_s"])


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


def _film_pixels(state: RenderState) -> int:
    """Pixels of the crushed film's red (the palette's DAMAGED) in the scene (the gauges left out), drawn as if
    undamaged: the film and a crushed object's undeformed surface are then the only parts in that colour."""
    from pneunet_env.envs.palette import DAMAGED

    img = render_frame(state._replace(damaged=False), 480, 360, label=False)[:340, 30:450].astype(int)
    return int(np.sum(np.abs(img - DAMAGED).max(axis=-1) <= 2))


def test_the_crushed_film_is_the_task_flag_not_the_thickness():
    """The film is drawn iff ``crushed`` (indentation past ``crush_indentation``), whatever ``H`` says."""
    contact = dict(curvature=0.0205, in_contact=True, contact_force=1e-3, pressure_fraction=0.5, object_thickness=2.0)
    deep_intact = _state(indentation=3.0, crush_indentation=5.0, **contact)  # past H, below the threshold
    shallow_crushed = _state(indentation=1.0, crush_indentation=0.5, **contact)  # above the threshold, within H
    assert not deep_intact.crushed and shallow_crushed.crushed
    assert not _state(indentation=3.0, crush_indentation=0.5, **{**contact, "in_contact": False}).crushed
    assert _film_pixels(deep_intact) == 0 and _film_pixels(shallow_crushed) > 500
    assert frame_status(deep_intact._replace(damaged=True)) == "damaged"
    assert frame_status(shallow_crushed._replace(damaged=True)) == "crushed"


@pytest.mark.parametrize("overrides", [
    {"damage_rule": "hoop_strain"},  # crush at eps_f/(w kappa_obj) = 15 w > H = 2 w: intact past H
    {"damage_rule": "hoop_strain", "object_failure_strain": (0.02, 0.02)},  # crush at 1 w < H: crushed within H
    {"damage_rule": "crush_fraction", "crush_fraction": 2.0},  # crush at 2 H: intact past H
    {"damage_rule": "crush_fraction", "crush_fraction": 0.5},  # crush at H/2: crushed within H
])
def test_the_env_draws_the_crushed_film_by_the_damage_rule_in_force(overrides):
    """Along a ramp, the env's frames show the film exactly on the steps its ``info["crushed"]`` is True, under
    both damage rules, with objects where the rule and ``indentation > H`` disagree."""
    env = gym.make("PneuNetGrasp-Paper-v0", render_mode="rgb_array", terminate_on_damage=False,
                   terminate_on_slip=False, **overrides)
    env.reset(seed=0, options={"object_stiffness": 1e-4})
    disagreements = 0
    for _ in range(12):
        info = env.step(np.array([1.0], np.float32))[-1]
        state = env.unwrapped.render_state()
        assert state.crushed == bool(info["crushed"])
        assert (_film_pixels(state) > 500) == bool(info["crushed"]), (state.indentation, state.crush_indentation)
        disagreements += bool(info["crushed"]) != (state.indentation > state.object_thickness)
    env.close()
    assert disagreements > 0  # the ramp passes a step where the thickness alone would draw the wrong picture


def test_render_modes_through_the_env(monkeypatch):
    env = gym.make("PneuNetGrasp-v1", render_mode="rgb_array", render_width=160, render_height=120,
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
    env = gym.make("PneuNetGrasp-v1", render_mode="human", render_width=160, render_height=120)
    env.reset(seed=0)
    env.step(np.array([1.0]))
    assert env.render() is None
    env.close()


def test_render_without_mode_warns_and_returns_none():
    env = gym.make("PneuNetGrasp-v1").unwrapped
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render"):
        assert env.render() is None


def test_png_round_trip_and_contact_sheet(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (17, 23, 3), dtype=np.uint8)
    path = save_png(tmp_path / "x.png", img)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert np.array_equal(read_png(path), img)
    sheet = contact_sheet([img] * 5, columns=2, gutter=3, legend=False)
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


def test_render_command_renders_catalogue_classes(tmp_path, capsys):
    from pneunet_env.cli import render as cmd

    parser = argparse.ArgumentParser()
    cmd.add_arguments(parser)
    args = parser.parse_args(["--out", str(tmp_path), "--object", "gelatin_gel", "apple", "--steps", "4",
                              "--columns", "2", "--seed", "2"])
    assert cmd.run(args) == 0
    names = {f.name.rsplit("_", 1)[0] for f in (tmp_path / "frames").glob("*.png")}
    assert names == {"gelatin_gel", "apple"}
    out = capsys.readouterr().out
    assert "gelatin_gel: k~=" in out and "apple: k~=" in out
    for bad, message in ((["--object", "bread"], "not a catalogue class inside the model"),  # outside the model
                         (["--object", "tofu"], "not a catalogue class inside the model"),
                         (["--object", "apple", "--stiffness", "1e-3"], "not both")):
        with pytest.raises(SystemExit, match=message):
            cmd.run(parser.parse_args(["--out", str(tmp_path), *bad]))


# ---- the text: a bitmap font, the frame's label, the contact sheet's legend ------------------------------------

_TEXT_DARK = (32, 36, 44)  # the label's text colour, and the state's: held/gripping, crushed/damaged, slipped
_TEXT_GREEN, _TEXT_RED, _TEXT_ORANGE = (24, 128, 52), (196, 20, 20), (204, 108, 0)


def _count(img, colour) -> int:
    return int(np.all(img == np.array(colour, np.uint8), axis=-1).sum())


def test_the_font_draws_each_glyph_distinctly():
    chars = [chr(c) for c in range(32, 127)]
    glyphs = [text_mask(c) for c in chars]
    assert all(g.shape == (FONT_HEIGHT, FONT_WIDTH) and g.dtype == bool for g in glyphs)
    assert not glyphs[0].any() and all(g.any() for g in glyphs[1:])  # a space is blank, nothing else is
    assert len({g.tobytes() for g in glyphs}) == len(chars)  # no two printable characters look alike
    # a line: glyphs set 6 pixels apart; an integer scale repeats each pixel; what is not printable ASCII is a "?"
    line = text_mask("k~=1.0e-4")
    assert line.shape == (FONT_HEIGHT, 9 * (FONT_WIDTH + 1) - 1)
    assert np.array_equal(line[:, 6:11], text_mask("~")) and not line[:, 5].any()
    assert np.array_equal(text_mask("kPa", 3), np.kron(text_mask("kPa"), np.ones((3, 3), bool)))
    assert np.array_equal(text_mask("\u00b5"), text_mask("?"))
    assert text_mask("").shape == (FONT_HEIGHT, 0)


def test_the_label_says_object_step_pressure_and_state():
    named = _state(object_name="apple", step=20, pressure_kpa=33.94, in_contact=True, contact_force=1e-2)
    assert [t for t, _ in label_lines(named)] == ["apple", "step 20", "33.9 kPa", "gripping"]
    unnamed = _state(object_stiffness=1e-4)  # the paper's task: no classes, the object is its stiffness
    assert label_lines(unnamed)[0][0] == "k~=1.0e-4" and label_lines(_state(object_stiffness=1.3))[0][0] == "k~=1.3e0"
    contact = dict(in_contact=True, indentation=0.5, contact_force=1e-3)
    cases = [
        (_state(), "free"),
        (_state(**contact), "squeezing"),  # below the grip traction (2e-3)
        (_state(**{**contact, "contact_force": 2e-3}), "gripping"),
        (_state(in_hold=True, **contact), "held"),
        (_state(in_hold=True, dropped=True), "slipped"),
        (_state(damaged=True, **contact), "damaged"),  # overstressed, not crushed through (0.5 < 2)
        (_state(damaged=True, dropped=True, **{**contact, "indentation": 2.5}), "crushed"),
    ]
    assert [frame_status(st) for st, _ in cases] == [w for _, w in cases]


def _corner(img):  # the label's corner: the top left third of the frame's width, the top quarter of its height
    return img[: img.shape[0] // 4, : img.shape[1] // 3]


def test_the_label_is_drawn_in_the_top_left_corner():
    st = _state(object_name="kiwifruit", step=7, pressure_kpa=12.3, curvature=0.3, pressure_fraction=0.4)
    for width, height in ((320, 240), (480, 360)):
        with_label, without = render_frame(st, width, height), render_frame(st, width, height, label=False)
        changed = np.any(with_label != without, axis=-1)
        rows, cols = np.nonzero(changed)
        assert rows.max() < height // 4 and cols.max() < width // 3  # in the corner, and only there
        assert _count(_corner(with_label), _TEXT_DARK) > 100
        assert np.array_equal(render_frame(st, width, height, label=True), with_label)
    assert np.array_equal(render_frame(st, 200, 150), render_frame(st, 200, 150, label=False))  # too small: none
    with pytest.raises(ValueError, match="200 px wide"):
        render_frame(st, 200, 150, label=True)
    with pytest.raises(ValueError, match="150 px high"):
        render_frame(st, 320, 150, label=True)
    assert (LABEL_MIN_WIDTH, LABEL_MIN_HEIGHT) == (240, 180)


def test_the_label_changes_with_the_pressure_and_the_state_in_its_colour():
    contact = dict(curvature=0.0205, in_contact=True, indentation=1.0, contact_force=1e-3, object_name="apple")

    def corner(**kw):
        return _corner(render_frame(_state(**{**contact, **kw}), 320, 240))

    base = corner(step=3, pressure_kpa=10.0)
    assert not np.array_equal(base, corner(step=3, pressure_kpa=20.0))
    assert not np.array_equal(base, corner(step=4, pressure_kpa=10.0))
    for kw, colour in ((dict(in_hold=True), _TEXT_GREEN), (dict(damaged=True), _TEXT_RED),
                       (dict(in_hold=True, dropped=True), _TEXT_ORANGE)):
        img = corner(**kw)
        assert _count(img, colour) > 20, kw  # the state, in its colour
        others = {_TEXT_GREEN, _TEXT_RED, _TEXT_ORANGE} - {colour}
        assert all(_count(img, c) == 0 for c in others), kw
    assert all(_count(base, c) == 0 for c in (_TEXT_GREEN, _TEXT_RED, _TEXT_ORANGE))  # "squeezing": no colour


def test_the_env_labels_its_frames_with_the_class_or_the_stiffness():
    def first_line(env_id, options=None):
        env = gym.make(env_id, render_mode="rgb_array", render_width=240, render_height=180)
        env.reset(seed=2, options=options)
        env.step(np.array([1.0], np.float32))
        state = env.unwrapped.render_state()
        frame = env.render()
        env.close()
        assert state.step == 1 and state.pressure_kpa > 0.0
        assert np.array_equal(frame, render_frame(state, 240, 180))
        assert not np.array_equal(frame, render_frame(state, 240, 180, label=False))
        return label_lines(state)[0][0]

    env = gym.make("PneuNetGrasp-v1")
    _, info = env.reset(seed=2)
    assert first_line("PneuNetGrasp-v1") == info["object_class"]  # a kitchen class
    assert first_line("PneuNetGrasp-v1", {"object_stiffness": 1e-4}) == "k~=1.0e-4"  # pinned: not the class's
    assert first_line("PneuNetGrasp-Paper-v0", {"object_stiffness": 1e-5}) == "k~=1.0e-5"  # no classes


def test_contact_sheets_carry_a_legend():
    frame = render_frame(_state(object_name="apple"), 320, 240)
    bare = contact_sheet([frame] * 4, columns=2, legend=False)
    sheet = contact_sheet([frame] * 4, columns=2)
    assert sheet.shape[1] == bare.shape[1] and sheet.shape[0] > bare.shape[0] + 2 * FONT_HEIGHT
    assert np.array_equal(sheet[: bare.shape[0]], bare)
    strip = sheet[bare.shape[0] :]
    assert np.array_equal(strip, legend_strip(bare.shape[1], margin=4))
    assert _count(strip, _TEXT_DARK) > 1000  # the words
    for colours, _ in LEGEND:  # each entry's swatches, in the palette's colours
        for c in colours:
            assert _count(strip, np.clip(np.rint(c), 0, 255)) > 0, c
    # the entries wrap to the width: a narrower sheet, a taller strip; a larger scale, larger words
    assert legend_strip(400).shape[0] > legend_strip(1600).shape[0]
    assert legend_strip(1600, scale=2).shape[0] > legend_strip(1600, scale=1).shape[0]


def _render_args(*argv):
    from pneunet_env.cli import render as cmd

    parser = argparse.ArgumentParser()
    cmd.add_arguments(parser)
    return cmd, parser.parse_args(list(argv))


def test_render_command_writes_the_sheet_alone_without_out(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing but the sheet may be written, here or anywhere
    cmd, args = _render_args("--stiffness", "1e-2", "--steps", "2", "--columns", "3", "--width", "240",
                             "--height", "180", "--sheet", "pics/sheet.png")
    assert cmd.run(args) == 0
    assert [p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")] == ["pics", "pics/sheet.png"]
    sheet = read_png(tmp_path / "pics" / "sheet.png")
    assert sheet.shape[1] == 3 * 240 + 4 * 4 and sheet.shape[0] > 180 + 2 * 4  # a row of frames, and the legend


def test_render_command_refuses_a_frame_too_small_for_its_label(tmp_path):
    cmd, _ = _render_args("--out", str(tmp_path))
    for bad, message in ((["--width", "200"], r"--width 200: .*\[240, 4096\]"),
                         (["--height", "100"], r"--height 100: .*\[180, 4096\]"),
                         (["--width", "5000"], r"--width 5000"),
                         ([], "give --out DIR .* or --sheet PNG"),
                         (["--env", "PneuNetGrasp-Paper-v0", "--object", "apple"], "has no classes")):
        out = [] if not bad else ["--out", str(tmp_path)]
        with pytest.raises(SystemExit, match=message):
            cmd.run(_render_args(*out, *bad)[1])
    config = tmp_path / "small.yaml"
    config.write_text("render:\n  width: 160\n  height: 120\n")
    with pytest.raises(SystemExit, match="render.width 160"):
        cmd.run(_render_args("--sheet", str(tmp_path / "s.png"), "--config", str(config))[1])
    assert not (tmp_path / "frames").exists() and not (tmp_path / "s.png").exists()


# The renderer's core: the scene, the rasteriser, the palette, the font, the PNG codec and the public module.
RENDER_CORE = ("render", "scene", "raster", "palette", "font", "png")


def _imports(path: Path, top_level_only: bool = False) -> set[str]:
    """The modules a file imports (every import, or only those at the module's top level)."""
    import ast

    tree = ast.parse(path.read_text())
    nodes = tree.body if top_level_only else ast.walk(tree)
    out: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
    return out


def test_the_render_core_imports_neither_matplotlib_nor_pillow():
    envs = Path(pneunet_env.__file__).parent / "envs"
    for name in RENDER_CORE:
        bad = {m for m in _imports(envs / f"{name}.py") if m.split(".")[0] in ("matplotlib", "PIL")}
        assert not bad, (name, bad)
    # the human window imports matplotlib, but only when one is opened
    viewer = envs / "viewer.py"
    assert "matplotlib" in _imports(viewer) and not any(
        m.split(".")[0] == "matplotlib" for m in _imports(viewer, top_level_only=True))
    # one concern a module, each under the house size (render.py held all of them, 972 lines)
    for name in (*RENDER_CORE, "viewer"):
        assert len((envs / f"{name}.py").read_text().splitlines()) <= 800, name


def test_drawing_and_saving_a_frame_loads_neither_matplotlib_nor_pillow(tmp_path):
    import subprocess

    code = ("import sys\nfrom pneunet_env.envs.render import contact_sheet, render_frame, save_png\n"
            "from pneunet_env.envs.scene import RenderState\nfrom pneunet_env.physics.params import ActuatorParams\n"
            "s = RenderState(0.2, 0.1, ActuatorParams(), 0.5, 0.02, 2.0, 1e-3, 0.5, True, 0.5, 2.0, 2e-3, False, "
            "False, False, 0.3, 0.5)\n"
            f"save_png({str(tmp_path / 'f.png')!r}, contact_sheet([render_frame(s)], 1))\n"
            "loaded = sorted(m for m in sys.modules if m.split('.')[0] in ('matplotlib', 'PIL'))\n"
            "assert not loaded, loaded\n")
    subprocess.run([sys.executable, "-c", code], check=True)
    assert read_png(tmp_path / "f.png").shape[1] == 480 + 2 * 4


def test_save_png_is_atomic(tmp_path, monkeypatch):
    """A failure half-way leaves the old file whole and no temporary file behind (the old writer wrote in place)."""
    import os

    path = save_png(tmp_path / "f.png", np.zeros((4, 5, 3), np.uint8))
    before = path.read_bytes()

    def fail(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="disk full"):
        save_png(path, np.full((6, 7, 3), 9, np.uint8))
    assert path.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["f.png"]


if __name__ == "__main__":  # python tests/envs/test_render.py: rewrite the reference frames
    sys.exit(_write_reference_frames())
