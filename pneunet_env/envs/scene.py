"""What a frame shows, as geometry: the finger and the object of one state, with no pixels (numpy only).

:class:`RenderState` is what one frame shows of an env's state (:func:`render_state`), in the model's units:
lengths in units of the chamber width ``w``, tractions in units of the shear modulus ``mu`` (``pressure_kpa`` is
the one physical value, for the label). :class:`SceneGeometry` places the parts:

* the **actuator**, ``chambers`` unit cells along an arc of the model's curvature ``kappa``, tangent to the x
  axis at the origin and curling downwards about its centre of curvature ``(0, -1/kappa)``; a point has an arc
  length ``s`` and a normal offset ``n`` (:func:`arc_coordinates`), and each part is a rectangle in ``(s, n)``:
  the stiff PDMS base (``|n| <= h_b/2``), the elastomer side walls (radial, thinned as they stretch,
  ``h_s (1+e_s)^-2``), the top wall (``h_m (1+e_m)^-2`` about ``n = d (1+e_s)``) and the cavities between them;
* the **object**, a layer of thickness ``H`` below its undeformed surface, an arc of curvature ``kappa_obj``
  concentric with the actuator once in contact and indented by ``delta = 1/kappa_obj - 1/kappa`` (drawn up to
  ``H``); the loaded zone is the object under the actuator, and the undeformed surface is drawn (dashed) where the
  actuator pushed it in. A *crushed* object (:attr:`RenderState.crushed`: the task's flag, by the damage rule in
  force) is drawn as a film on the base, and its undeformed surface in red; an intact one indented past ``H`` (the
  ``hoop_strain`` rule allows it) is not.

The picture is symmetric in ``x``: every boundary is a circle (about the centre of curvature, or the object's
centre) or a radial line, so along a horizontal line at height ``y`` a part covers one interval of ``|x|``, found
in closed form (:meth:`SceneGeometry.x_radius`, :meth:`~SceneGeometry.x_normal`, :meth:`~SceneGeometry.x_arc`).
:func:`scene_parts` lists the parts in paint order, each as that interval along each line and the part's own
test at a point (which decides a point lying on a boundary, to rounding). The rasteriser
(:mod:`pneunet_env.envs.raster`) turns them into pixels.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from pneunet_env.physics.params import ActuatorParams

__all__ = [
    "RenderState", "render_state", "SceneGeometry", "ScenePart", "SceneParts", "scene_parts", "arc_coordinates",
    "normal_offset", "BAND", "DENT", "BODY", "BASE",
]


class RenderState(NamedTuple):
    """What one frame shows (dimensionless: lengths / ``w``, tractions / ``mu``)."""

    curvature: float  # kappa~ of the base
    side_strain: float  # e_s
    params: ActuatorParams
    pressure_fraction: float  # p / p_max
    object_curvature: float  # w kappa_obj
    object_thickness: float  # H / w
    contact_force: float  # F~
    indentation: float  # delta~ (0 out of contact)
    in_contact: bool
    failure_traction: float  # F~ at failure
    crush_indentation: float  # delta~ above which it is crushed (the damage rule in force)
    grip_traction: float  # F~ needed to hold it
    damaged: bool
    dropped: bool
    in_hold: bool
    progress: float  # step / episode length
    hold_start: float  # squeeze_steps / episode length
    # what the label says (see :func:`pneunet_env.envs.render.label_lines`); the defaults draw a label of an
    # unnamed object at step 0
    step: int = 0
    pressure_kpa: float = 0.0
    object_name: str = ""  # a catalogue class; "" names the object by its stiffness
    object_stiffness: float = math.nan  # k~

    @property
    def crushed(self) -> bool:
        """The task's *crushed* flag now: in contact and indented past ``crush_indentation``.

        ``crush_indentation`` is the env's own threshold (its state's ``thresholds``, set by the config's
        ``damage_rule``: ``eps_f / (w kappa_obj)`` for ``hoop_strain``, ``crush_fraction H`` for ``crush_fraction``),
        compared as :func:`pneunet_env.task.make_rules` compares it, so the picture says crushed exactly when
        ``info["crushed"]`` does; the object's thickness ``H`` plays no part.
        """
        return bool(self.in_contact) and float(self.indentation) > float(self.crush_indentation)


def render_state(
    state, params, i: int | None = None, class_names: tuple[str, ...] = (), object_name: str | None = None
) -> RenderState:
    """What a frame shows of an env's :class:`pneunet_env.task.EnvState` (of its entry ``i`` for a batch).

    The label names the object by ``object_name`` if given, else by its catalogue class (``class_names``, by the
    object's class code), else (``""``: no class, e.g. the paper's task) by its stiffness ``k~``.
    """

    def at(v):
        return v if i is None else v[i]

    eq, obj, thr, st, tp = state.eq, state.obj, state.thresholds, state.task, params.task
    step = int(at(st.step))
    in_contact = bool(at(eq.in_contact))
    if object_name is None:
        cid = int(at(obj.class_id))
        object_name = class_names[cid] if 0 <= cid < len(class_names) else ""
    return RenderState(
        curvature=float(at(eq.curvature)),
        side_strain=float(at(eq.side_strain)),
        params=params.actuator_params,
        pressure_fraction=float(at(state.command)) / tp.pressure_max,
        object_curvature=float(at(obj.curvature)),
        object_thickness=float(at(obj.thickness)),
        contact_force=float(at(eq.contact_force)),
        indentation=float(at(eq.indentation)) if in_contact else 0.0,
        in_contact=in_contact,
        failure_traction=float(at(thr.failure_traction)),
        crush_indentation=float(at(thr.crush_indentation)),
        grip_traction=float(at(thr.grip_traction)),
        damaged=bool(at(st.damaged)),
        dropped=bool(at(st.dropped)),
        in_hold=step > tp.squeeze_steps,
        progress=step / tp.episode_steps,
        hold_start=tp.squeeze_steps / tp.episode_steps,
        step=step,
        pressure_kpa=float(at(eq.pressure)) * tp.shear_modulus_kpa,
        object_name=str(object_name),
        object_stiffness=float(at(obj.stiffness)),
    )


def arc_coordinates(X, Y, kappa):
    """Arc length ``s`` and outward normal offset ``n`` of points, for an arc through the origin.

    The arc has curvature ``kappa >= 0``, is tangent to the x axis at the origin and curls downwards
    (centre at ``(0, -1/kappa)``); ``s`` is measured along it from the origin and ``n`` away from the
    centre. Exact and smooth as ``kappa -> 0`` (``s = X``, ``n = Y``). Lengths in units of ``w``.
    """
    k = float(kappa)
    q = np.hypot(k * X, 1.0 + k * Y)
    n = (k * (X * X + Y * Y) + 2.0 * Y) / (q + 1.0)
    s = np.arctan2(k * X, 1.0 + k * Y) / k if k > 1e-12 else X
    return s, n


def normal_offset(k: float, x, y):
    """The actuator's normal offset ``n`` of points (exact and smooth as ``k -> 0``; lengths in units of ``w``)."""
    q = np.sqrt((k * x) ** 2 + (1.0 + k * y) ** 2)
    return (k * (x * x + y * y) + 2.0 * y) / (q + 1.0)


class SceneGeometry:
    """One state's shapes: where each boundary crosses a horizontal line, and the exact tests at a point.

    Lengths in units of ``w``, ``y`` up, the origin at the middle of the base's centre-line; the ``x_*`` methods
    take the heights ``y`` of the lines (a 1-D array) and give ``|x|`` (the shapes are symmetric).
    """

    def __init__(self, state: RenderState, chambers: int) -> None:
        prm = state.params
        d, hb, hs, hm = prm.chamber_height, prm.base_thickness, prm.side_thickness, prm.top_thickness
        self.chambers = int(chambers)
        self.k = k = max(float(state.curvature), 0.0)
        self.flat = k <= 1e-12
        es = float(state.side_strain)
        self.L = float(chambers)
        # the object: a layer of thickness H below its undeformed surface (radius R_u about (0, oy)), concentric
        # with the actuator once in contact and indented by delta (drawn up to H)
        self.R_u = 1.0 / float(state.object_curvature) - 0.5 * hb  # its undeformed surface (base's lower face)
        self.H = H = float(state.object_thickness)
        self.delta = delta = max(float(state.indentation), 0.0) if state.in_contact else 0.0
        self.crushed = state.crushed  # the task's flag (a film on the base), not a rule of the picture's own
        self.delta_draw = min(delta, H)
        self.oy = -0.5 * hb + self.delta_draw - self.R_u
        # the actuator: offsets n of its parts (the top wall thinned as it stretches, the side walls too)
        em = d * (1.0 + es) * k
        tm = hm * (1.0 + em) ** -2
        self.ts = hs * (1.0 + es) ** -2
        n_top = d * (1.0 + es)  # the top wall's centre-line
        self.n_film = -0.5 * hb - 0.15 * min(H, 1.0)
        self.n_low = -0.5 * hb  # the base's lower face
        self.n_base = 0.5 * hb  # the base's upper face
        self.n_cavity = n_top - 0.5 * tm  # the cavities' roof
        self.n_top = n_top + 0.5 * tm  # the top wall's outer face
        self.hb = hb

    # ---- where the tests change along each line (|x|; inf: nowhere) -------------------------------------
    def x_radius(self, y: np.ndarray, radius: float):
        """First ``|x|`` with ``hypot(x, y - oy) >= radius``."""
        yo = y - self.oy
        if radius <= 0.0:
            return np.zeros(yo.shape)
        return np.sqrt(np.maximum((radius - yo) * (radius + yo), 0.0))

    def x_normal(self, y: np.ndarray, cs, strict):
        """First ``|x|`` with the normal offset ``n >= c`` (``n > c`` where ``strict``), for each ``c`` of ``cs``.

        ``n`` grows with ``|x|``: ``n = rho - 1/k`` with ``rho`` the distance to the centre of curvature
        ``(0, -1/k)``, so ``n = c`` at ``x^2 = (c + 1/k)^2 - (y + 1/k)^2 = (c - y)(c + y + 2/k)``; flat
        (``k <= 1e-12``): ``n = y``.
        """
        k = self.k
        c = np.asarray(cs, float)[:, None]
        if self.flat:
            inside = np.where(np.asarray(strict)[:, None], y > c, y >= c)
            return np.where(inside, 0.0, np.inf)
        x = np.sqrt(np.maximum((c - y) * (c + y + 2.0 / k), 0.0))
        return np.where(c + 1.0 / k <= 0.0, 0.0, x)

    def x_arc(self, y: np.ndarray, ss):
        """Where the radial line at arc length ``s >= 0`` crosses each line, for each ``s`` of ``ss`` (inf: never).

        Along a line (``x >= 0``) the arc length ``atan2(k x, 1 + k y) / k`` is monotonic: it grows with ``x``
        above the centre of curvature and shrinks below it. Flat: ``s = x``.
        """
        k = self.k
        s = np.asarray(ss, float)[:, None]
        if self.flat:
            return np.broadcast_to(s, (len(s), len(y)))
        phi = np.minimum(k * s, math.pi)
        a = 1.0 + k * y  # k (y + 1/k): > 0 above the centre
        with np.errstate(over="ignore"):
            x = a * (np.tan(phi) / k)
        crosses = ((phi < 0.5 * math.pi) & (a > 0.0)) | ((phi > 0.5 * math.pi) & (a < 0.0))
        return np.where(crosses, x, np.inf)

    # ---- the tests at points (X, Y), computed as the picture defines them --------------------------------
    def arc(self, X, Y):
        """Arc length ``s`` and normal offset ``n`` of points."""
        return arc_coordinates(X, Y, self.k)

    def radial(self, X, Y):
        """Signed distance to the object's undeformed surface (negative inside)."""
        Yo = Y - self.oy
        return (X * X + Yo * Yo - self.R_u * self.R_u) / (np.hypot(X, Yo) + self.R_u)

    def cells(self) -> list[tuple[int, float, float]]:
        """The cavities between the side walls with a part at ``x >= 0``: ``(index, s0, s1)``, their arc lengths
        (``s0 >= 0``)."""
        L, ts = self.L, self.ts
        cells = []
        s_max = 0.5 * L if self.flat else min(0.5 * L, math.pi / self.k)
        for m in range(self.chambers):
            s0, s1 = m + 0.5 * ts - 0.5 * L, m + 1.0 - 0.5 * ts - 0.5 * L
            if s0 < s1 and s1 > 0.0 and max(s0, 0.0) < s_max:
                cells.append((m, max(s0, 0.0), s1))
        return cells


class ScenePart(NamedTuple):
    """One part along the lines: it covers ``xlo <= |x| < xhi`` (arrays, one entry a line); ``test(X, Y)`` is its
    own definition at points (a bool array), which decides a point on its boundary."""

    xlo: np.ndarray
    xhi: np.ndarray
    test: Callable


class SceneParts(NamedTuple):
    """The parts in paint order: :data:`BAND` (the object's layer), :data:`DENT` (the actuator and above: no
    object material), :data:`BODY` (the actuator), :data:`BASE` (its base), then the optional ones (their index,
    or ``None`` if absent) and the cavities (``first_cell`` on)."""

    parts: list[ScenePart]
    zone: int | None  # the loaded zone: the object under the actuator
    film: int | None  # what is left of a crushed object (the task's flag): a film on the base
    dash: int | None  # the undeformed surface where the actuator pushed the object in
    first_cell: int


BAND, DENT, BODY, BASE = range(4)


def scene_parts(g: SceneGeometry, y: np.ndarray, eps: float) -> SceneParts:
    """Every part of the scene along the horizontal lines at heights ``y`` (units of ``w``); ``eps`` is the
    half-width of the undeformed surface's line (units of ``w``)."""
    L, ts = g.L, g.ts

    def test_band(X, Y):
        rmr = g.radial(X, Y)
        return (rmr <= 0.0) & (rmr >= -g.H)

    def test_actuator(lo, hi, strict_lo=False, strict_hi=False, cell=None):
        def test(X, Y):
            s, n = g.arc(X, Y)
            inside = (np.abs(s) <= 0.5 * L) & ((n > lo) if strict_lo else (n >= lo))
            inside &= (n < hi) if strict_hi else (n <= hi)
            if cell is not None:
                u = s + 0.5 * L
                frac = u - np.floor(u)
                inside &= (frac > 0.5 * ts) & (frac < 1.0 - 0.5 * ts) & (np.floor(u) == cell)
            return inside

        return test

    def test_zone(X, Y):
        return test_band(X, Y) & test_actuator(-np.inf, g.n_low)(X, Y)

    def test_dash(X, Y):
        return test_actuator(g.n_low, np.inf, strict_lo=True)(X, Y) & (np.abs(g.radial(X, Y)) <= eps)

    cells = g.cells()
    arc = g.x_arc(y, [0.0, 0.5 * L] + [s for _, s0, s1 in cells for s in (s0, s1)])
    span_x0, span_x1 = np.minimum(arc[0], arc[1]), np.maximum(arc[0], arc[1])  # |s| <= L/2
    n_low_gt, n_low, n_top, n_base, n_cavity, n_film = g.x_normal(
        y, [g.n_low, g.n_low, g.n_top, g.n_base, g.n_cavity, g.n_film], [True, False, True, True, False, False]
    )
    dent_x0 = np.maximum(span_x0, n_low_gt)  # the actuator and above: no object material
    body_x0 = np.maximum(span_x0, n_low)
    band_x0, band_x1 = g.x_radius(y, g.R_u - g.H), g.x_radius(y, g.R_u)
    parts = [
        ScenePart(band_x0, band_x1, test_band),
        ScenePart(dent_x0, span_x1, test_actuator(g.n_low, np.inf, strict_lo=True)),
        ScenePart(body_x0, np.minimum(span_x1, n_top), test_actuator(g.n_low, g.n_top)),
        ScenePart(body_x0, np.minimum(span_x1, n_base), test_actuator(g.n_low, g.n_base)),
    ]
    zone = film = dash = None
    if g.delta > 0.0:  # the loaded zone: the object under the actuator
        zone = len(parts)
        parts.append(ScenePart(np.maximum(band_x0, span_x0), np.minimum(np.minimum(band_x1, dent_x0), span_x1),
                               test_zone))
    if g.crushed:  # crushed (the task's flag): a film on the actuator's base
        film = len(parts)
        parts.append(ScenePart(np.maximum(span_x0, n_film), np.minimum(span_x1, n_low_gt),
                               test_actuator(g.n_film, g.n_low)))
    if g.delta_draw > 0.0:  # the undeformed surface where the actuator pushed the object in
        dash = len(parts)
        parts.append(ScenePart(np.maximum(g.x_radius(y, g.R_u - eps), dent_x0),
                               np.minimum(g.x_radius(y, g.R_u + eps), span_x1), test_dash))
    first_cell = len(parts)
    cav_x0, cav_x1 = np.maximum(span_x0, n_base), np.minimum(span_x1, n_cavity)
    for i, (m, _, _) in enumerate(cells):
        x0, x1 = arc[2 + 2 * i], arc[3 + 2 * i]
        parts.append(ScenePart(np.maximum(np.minimum(x0, x1), cav_x0), np.minimum(np.maximum(x0, x1), cav_x1),
                               test_actuator(g.n_base, g.n_cavity, True, True, cell=m)))
    return SceneParts(parts, zone, film, dash, first_cell)
