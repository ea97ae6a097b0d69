"""``pneunet-grasp design``: which actuator lets one blind pressure schedule hold a use case's objects, with margin.

The seed paper's §4 ("general criteria for actuator design") says that the walls' thicknesses, the chamber's
shape, the elastomer's modulus and its Gent limit shape the pressure-curvature curve, and so where one blind
pressure is safe for soft objects yet firm enough for stiff ones. This module turns that into a search:

* **The design space** (:data:`DESIGN_SPACE`): the top, side and base wall thicknesses, the chamber height and
  width, the finger in 3D (its width ``t + 2 h_s``, capped at the narrowest object, its length and 2 or 3 fingers:
  what the hold rule carries the weight on), and the elastomer, one of the commercial casting elastomers of
  ``pneunet_env/data/elastomers.yaml`` (its small-strain shear modulus ``mu`` and Gent limit ``J`` from a fit to
  measured curves, each with its source), or the paper's Table 1 material. A design with a low Gent limit and a
  soft modulus is therefore always a material one can buy. Every bound says where it comes from (:class:`Bound`).
* **The pressure scale follows the elastomer.** A design's ``max_pressure_kpa`` is ``1.2 mu`` (the paper's
  ``p~ = 1.2``, Table 1's 60 kPa) and its step ``0.06 mu`` (Table 1's 3 kPa), so a stiffer elastomer is not
  cut off at 60 kPa (:func:`design_config`).
* **One evaluation of a design** (:func:`evaluate_design`) is batched (:mod:`agents.evaluation.batch`): every object x
  every candidate blind pressure (:data:`TARGETS`, 60 ramps to ``p~ = 0.02 .. 1.2``) is one vector env run. From it:

  - the blind ramp: the centre of the pressure window around the best point (the search's rule: most objects held;
    ties to the higher mean return, then the middle), robust to a regulator's error;
  - its success on force- and position-controlled objects, by Table 1's labels (the same split for every
    design: what the objects are) and by the design's own (what its mechanics make of them);
  - the grid oracle: whether *some* constant pressure of the grid holds each object (what a schedule that
    knew the object could reach with this actuator: a design that makes objects ungraspable shows here);
  - the pressure window: the contiguous range of blind pressures whose success stays within 5 points of the
    best, as a fraction of the best pressure;
  - the worst corner: the *same* schedule (kPa) at every corner (walls x0.9 / x1.1 crossed with the modulus
    x0.8 / x1.2, the elastomer's data range, the blind pressure -/+ the regulator's error, ``--pressure-error-kpa``):
    :func:`agents.design.space.corner_configs`; the largest wall stretch at the blind pressure, flagged when it
    passes the stretch the material was fitted on;
  - the success under random manufacturing error, a second figure: :data:`N_ERRORS` perturbed actuators (wall
    thicknesses uniform within +-10 %, modulus within +-20 %, the same draws for every design), each object
    meeting one of them, drawn per object.

* **The search** runs on Optuna (a multi-objective TPE or NSGA-II sampler) over three objectives to maximise:
  blind success on force-controlled objects, on position-controlled ones (Table 1's labels: a Pareto pair),
  and the worse of the two at the worst corner. Its storage is a SQLite file in the output folder, so a
  stopped run resumes where it stopped; ``--storage URL`` names any Optuna storage (an RDB URL, or
  ``journal:PATH`` for a journal file), so workers on several machines join one study, and ``--jobs N`` runs
  N worker processes here. The Table 1 design is always trial 0.
* **Held out.** Designs are searched on ``--objects`` objects (seeds ``seed * 1_000_003 + i``) and the best are
  reported on ``--held-out`` others (the demo's seeds), with the blind schedule found on the search objects.

The best design is the one whose worst of (blind force-controlled, blind position-controlled, both at the worst
corner) is highest, ties to the wider window (:func:`design_rank`). Outputs (``--out DIR``): ``design.json``,
``pareto.png``, ``curves.png`` (the pressure-curvature curves of the best designs beside Table 1, in the style
of the paper's Fig. 3), ``importance.png`` (Optuna's PED-ANOVA importance of each parameter for the design score),
and ``designs/rank-K.yaml``: each best design as an env config, with its tuned ramp beside it
(``rank-K.best_ramp.json``, which ``pneunet-grasp demo --config rank-K.yaml`` runs). ``--export PATH.yaml`` also
writes the best one there.

The model is one chamber of uniform curvature, with one modulus and one ``J`` for both walls: see
``docs/design.md`` for what a designer would also want, and what each would take.
"""

from __future__ import annotations

from agents.design.cli import add_arguments, main, run
from agents.design.score import DesignScore, design_rank, evaluate_design, reference_regimes
from agents.design.space import (
    DESIGN_SPACE,
    N_ERRORS,
    P_TILDE_MAX,
    TARGETS,
    Bound,
    Elastomer,
    design_config,
    elastomers,
    parse_bounds,
    perturbed_config,
    table1_design,
    validity,
)
from agents.design.study import StudySpec, open_study, report, run_study, work

__all__ = ["Bound", "Elastomer", "DESIGN_SPACE", "TARGETS", "N_ERRORS", "P_TILDE_MAX", "elastomers", "validity",
           "design_config", "perturbed_config", "table1_design", "DesignScore", "evaluate_design", "design_rank",
           "reference_regimes", "StudySpec", "open_study", "work", "run_study", "report", "parse_bounds",
           "add_arguments", "run", "main"]
