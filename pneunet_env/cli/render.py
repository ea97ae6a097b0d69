"""``pneunet-grasp render``: save PNG frames (and a contact sheet) of episodes under a pressure ramp.

For each object stiffness ``k~`` (``--stiffness``, several allowed), one episode of ``PneuNetGrasp-v1``
(``--env PneuNetGrasp-Paper-v0``: the paper's task, its 250 mm ring) is run with the object pinned and the
scripted :class:`agents.policies.scripted.LinearRamp` to ``--target`` of ``p_max`` over ``--steps`` steps; every frame
is saved as ``OUT/frames/k<K>_<step>.png`` and a contact sheet (one row per stiffness, ``--columns`` frames evenly
spaced in time, over a legend of the colours) as ``OUT/sheet.png``. ``--object NAME ...`` instead runs one episode
per catalogue class (the env draws its object from that class alone, ``class_weights: {NAME: 1}``, with the reset
seed), frames ``OUT/frames/<NAME>_<step>.png``.

``--sheet PNG`` also writes the contact sheet there; with ``--sheet`` and no ``--out`` only that sheet is written
(no frames, no folder). One of ``--out`` and ``--sheet`` is needed. Each frame carries its label (the object, the
step, the pressure, the state), so frames must be at least 240 x 180 pixels (``--width``/``--height``, or the
config's ``render`` size); a smaller size is refused with a message naming it.
PNGs are written with :func:`pneunet_env.envs.render.save_png` (zlib only; no matplotlib needed), atomically: an
existing sheet or frame is replaced whole, never left half-written. Every value is checked before the first episode:
``--out`` must be a folder that exists or can be created, ``--sheet`` a file that can be written; a bad value is one
line, exit status 2.
"""

from __future__ import annotations

import argparse

import numpy as np

from pneunet_env import arguments as checks
from pneunet_env.progress import add_progress_argument, progress

DEFAULT_STIFFNESS = (1e-5, 1e-4, 1e-2)
"""The default episodes' ``k~``: soft, through the paper ring's fold, stiff."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=checks.output_dir, default=None,
                        help="output folder (created): every frame under OUT/frames/ and the sheet as OUT/sheet.png; "
                             "optional with --sheet (then only the sheet is written, no frames)")
    parser.add_argument("--stiffness", type=checks.non_negative, nargs="+", default=None,
                        help="object stiffness(es) k~ = k_obj w/mu, one episode each (default "
                             f"{' '.join(f'{k:.0e}' for k in DEFAULT_STIFFNESS)})")
    parser.add_argument("--object", nargs="+", default=None, metavar="CLASS",
                        help="catalogue class(es), one episode each, the object drawn from that class (instead of "
                             "--stiffness), e.g. gelatin_gel kiwifruit apple")
    parser.add_argument("--steps", type=checks.integer(1, 100_000), default=40,
                        help="ramp steps from 0 to the target (default 40)")
    parser.add_argument("--target", type=checks.real(0.0, 1.0), default=1.0,
                        help="ramp target, fraction of p_max in [0, 1] (default 1)")
    parser.add_argument("--columns", type=checks.integer(1, 100), default=6,
                        help="frames per stiffness on the sheet, 1 to 100 (default 6)")
    parser.add_argument("--config", default=None, help="environment config YAML (default: the built-in defaults)")
    parser.add_argument("--env", default="PneuNetGrasp-v1", choices=("PneuNetGrasp-v1", "PneuNetGrasp-Paper-v0"),
                        help="the environment (default PneuNetGrasp-v1; PneuNetGrasp-Paper-v0: the paper's ring)")
    parser.add_argument("--keep-going", action="store_true",
                        help="do not end the episode on damage or slip (flagged, drawn in red), to see the whole ramp")
    parser.add_argument("--width", type=int, default=None,
                        help="frame width in px, at least 240 for the label (default: the config's, 480)")
    parser.add_argument("--height", type=int, default=None,
                        help="frame height in px, at least 180 for the label (default: the config's, 360)")
    parser.add_argument("--seed", type=checks.seed, default=0, help="reset seed (default 0)")
    parser.add_argument("--sheet", type=checks.output_file, default=None,
                        help="write the contact sheet (frames over a legend) to this path too; without --out, only it")
    add_progress_argument(parser)


def run(args: argparse.Namespace) -> int:
    import gymnasium as gym

    import pneunet_env  # (registers the environment)
    from agents.policies.scripted import LinearRamp
    from pneunet_env.config import MAX_RENDER_PIXELS, load_config
    from pneunet_env.envs.render import LABEL_MIN_HEIGHT, LABEL_MIN_WIDTH, contact_sheet, save_png

    if args.out is None and args.sheet is None:
        raise SystemExit("give --out DIR (the frames and the sheet) or --sheet PNG (the sheet alone), or both")
    if args.steps < 1:
        raise SystemExit(f"--steps must be >= 1, got {args.steps}")
    if args.columns < 1:
        raise SystemExit(f"--columns must be >= 1, got {args.columns}")
    for name, value, least in (("width", args.width, LABEL_MIN_WIDTH), ("height", args.height, LABEL_MIN_HEIGHT)):
        if value is not None and not least <= value <= MAX_RENDER_PIXELS:
            raise SystemExit(f"--{name} {value}: a frame's {name} must be in [{least}, {MAX_RENDER_PIXELS}] pixels "
                             f"(at least {LABEL_MIN_WIDTH} x {LABEL_MIN_HEIGHT} to carry its label)")
    overrides = {"terminate_on_damage": False, "terminate_on_slip": False} if args.keep_going else {}
    if args.width is not None:
        overrides["render_width"] = args.width
    if args.height is not None:
        overrides["render_height"] = args.height
    env_kwargs = dict(pneunet_env.PAPER_TASK) if args.env == pneunet_env.PAPER_ENV_ID else {}
    try:
        render_config = load_config(args.config, **env_kwargs, **overrides).render
    except ValueError as exc:
        raise SystemExit(f"render: {exc}") from None
    for name, value, least in (("width", render_config.width, LABEL_MIN_WIDTH),
                               ("height", render_config.height, LABEL_MIN_HEIGHT)):
        if value < least:  # from the config (--width/--height were checked above)
            raise SystemExit(f"render.{name} {value} (from --config): a frame must be at least {LABEL_MIN_WIDTH} x "
                             f"{LABEL_MIN_HEIGHT} pixels to carry its label; pass --{name}")
    if args.object is not None and args.stiffness is not None:
        raise SystemExit("give --stiffness or --object, not both")
    if args.object is not None and env_kwargs:
        raise SystemExit(f"--object needs the catalogue: {args.env} has no classes (use --stiffness)")
    if args.object is not None:  # (name, overrides, reset options) per episode
        from pneunet_env.catalogue import load_catalogue

        known = load_catalogue()
        for name in args.object:
            if name not in known or not known[name].in_annulus_model:
                inside = sorted(n for n, c in known.items() if c.in_annulus_model)
                raise SystemExit(f"--object {name!r}: not a catalogue class inside the model; one of {inside}")
        episodes = [(name, {"class_weights": {name: 1.0}}, None) for name in dict.fromkeys(args.object)]
    else:
        stiffness = dict.fromkeys(args.stiffness or DEFAULT_STIFFNESS)
        episodes = [(f"k{k:.0e}", {}, {"object_stiffness": k}) for k in stiffness]
    frames_dir = None if args.out is None else args.out / "frames"
    if frames_dir is not None:
        frames_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    bar = progress(total=len(episodes) * (args.steps + 1), desc="render", unit="frame", enabled=args.progress)
    for tag, extra, options in episodes:
        bar.set_description_str(f"render {tag}")
        env = gym.make(args.env, render_mode="rgb_array", config=args.config, **overrides, **extra)
        policy = LinearRamp(args.target, args.steps, env.unwrapped.config)
        obs, info = env.reset(seed=args.seed, options=options)
        k = info["object_stiffness"]
        frames = [env.render()]
        bar.update()
        events = []
        for t in range(1, args.steps + 1):
            obs, _, terminated, truncated, info = env.step(policy(obs))
            frames.append(env.render())
            bar.update()
            if info["damaged"] and not any(e.startswith("damaged") for e in events):
                events.append(f"damaged at step {t}")
            if terminated or truncated:
                break
        env.close()
        bar.update(args.steps + 1 - len(frames))  # the steps of an episode that ended early
        if frames_dir is not None:
            for t, f in enumerate(frames):
                save_png(frames_dir / f"{tag}_{t:03d}.png", f)
        idx = np.unique(np.linspace(0, len(frames) - 1, args.columns).round().astype(int))
        row = [frames[i] for i in idx]
        row += [np.full_like(frames[0], 255)] * (args.columns - len(row))
        rows.extend(row)
        bar.write(
            f"{tag}: k~={k:.2e}, {len(frames)} frames, final p={info['pressure_kpa']:.1f} kPa, "
            f"curvature {info['curvature_per_m']:.1f} /m, traction {info['contact_force_kpa']:.3g} kPa"
            + (f", {events[0]}" if events else "")
        )
    bar.close()
    sheet = contact_sheet(rows, args.columns)
    if args.out is not None:
        path = save_png(args.out / "sheet.png", sheet)
        print(f"wrote {frames_dir}/*.png and {path}")
    if args.sheet is not None:
        save_png(args.sheet, sheet)
        print(f"wrote {args.sheet}")
    return 0
