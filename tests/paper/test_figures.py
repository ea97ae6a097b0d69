"""``pneunet-grasp figures``: files, CSV columns, PNGs, and the data functions behind them."""

from __future__ import annotations

import ast
import importlib
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pneunet_env import ActuatorParams, cli, paper
from pneunet_env.paper import command
from pneunet_env.paper.checks import CHECKS
from pneunet_env.paper.figures import (
    COLUMNS,
    FIGURES,
    REGIMES,
    CurveSpec,
    Table,
    classify_regimes,
    compute_curve,
    compute_figures,
    critical_pressure,
    linear_rows,
    load_tables,
    loading,
    pressure_grid,
    read_table,
    unloading,
    write_table,
)

REQUIRED = ("pressure", "curvature", "contact_force", "object_stiffness", "gent_limit", "branch")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("figures")
    rc = cli.main(["figures", "--out", str(out), "--quick", "--no-progress"])
    return out, rc


@pytest.mark.slow  # the quick figure run (7 s) they share; the README's test command runs it
def test_quick_run_writes_every_figure(quick_run):
    out, rc = quick_run
    assert rc == 0
    for name in FIGURES:
        assert (out / f"{name}.png").is_file(), name
        assert (out / f"{name}.csv").is_file(), name
    table = (out / "paper_checks.md").read_text()
    assert table.startswith("| # | statement")
    rows = [line for line in table.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == len(CHECKS)


@pytest.mark.slow  # the quick figure run (7 s) they share; the README's test command runs it
def test_pngs_are_real_images(quick_run):
    import matplotlib.image as mpimg

    out, _ = quick_run
    for name in FIGURES:
        path = out / f"{name}.png"
        assert path.read_bytes()[:8] == PNG_MAGIC, name
        assert path.stat().st_size > 20_000, name
        img = mpimg.imread(path)
        assert img.shape[0] > 300 and img.shape[1] > 500, (name, img.shape)
        # Not a blank canvas: many distinct colours, real contrast.
        rgb = img[..., :3].reshape(-1, 3)
        assert rgb.std() > 0.05, name
        q = (rgb * 255).astype(np.int64)
        assert np.unique(q[:, 0] * 65536 + q[:, 1] * 256 + q[:, 2]).size > 50, name


@pytest.mark.slow  # the quick figure run (7 s) they share; the README's test command runs it
def test_csv_columns_and_branches(quick_run):
    out, _ = quick_run
    for name in FIGURES:
        t = read_table(out / f"{name}.csv")
        assert set(REQUIRED) <= set(t.columns), name
        assert list(t.columns) == list(COLUMNS), name
        assert set(t["branch"].tolist()) == {"loading", "unloading"}, name
        assert set(t["regime"].tolist()) <= set(REGIMES), name
        full = t.where(model="full")
        assert np.all(np.isfinite(full["curvature"])) and np.all(full["converged"]), name
        assert np.all((full["pressure"] >= 0) & (full["pressure"] <= 1.2 + 1e-12)), name
        # Every curve has a loading and an unloading branch on the same pressure grid.
        for s in full.unique("series"):
            lo, un = loading(full, series=s), unloading(full, series=s)
            np.testing.assert_array_equal(lo["pressure"], un["pressure"])


@pytest.mark.slow  # the quick figure run (7 s) they share; the README's test command runs it
def test_fig2_has_the_caption_values(quick_run):
    out, _ = quick_run
    t = read_table(out / "fig2.csv")
    assert sorted(set(t["object_stiffness"].tolist())) == [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2]
    assert set(t["gent_limit"].tolist()) == {15.0}
    assert set(t["object_curvature"].tolist()) == {0.02}
    assert set(t["chamber_height"].tolist()) == {1.0}
    assert set(t["top_thickness"].tolist()) == set(t["side_thickness"].tolist()) == {0.5}
    assert set(t["base_modulus"].tolist()) == {60.0} and set(t["poisson_ratio"].tolist()) == {0.5}
    f3 = read_table(out / "fig3.csv")
    assert set(f3["gent_limit"].tolist()) == {20.0}
    assert sorted(set(f3.where(sweep="top_thickness")["top_thickness"].tolist())) == [0.25, 0.375, 0.5, 0.625, 0.75]


@pytest.mark.slow  # the quick figure run (7 s) they share; the README's test command runs it
def test_table_only_reads_the_csvs(quick_run, capsys):
    out, _ = quick_run
    capsys.readouterr()
    assert cli.main(["figures", "--out", str(out), "--table-only"]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("| # | statement") and "✓" in printed


def test_only_writes_the_named_figure(tmp_path):
    assert cli.main(["figures", "--out", str(tmp_path), "--quick", "--no-progress", "--only", "supp_fig3"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["supp_fig3.csv", "supp_fig3.png"]


def test_table_only_without_data_fails_clearly(tmp_path):
    with pytest.raises(FileNotFoundError, match="fig2.csv"):
        load_tables(tmp_path)


def test_unknown_figure_is_a_value_error():
    with pytest.raises(ValueError, match="unknown figure"):
        compute_figures(None, ["fig9"])  # type: ignore[arg-type]


def test_pressure_grid():
    g = pressure_grid(0.1)
    assert g[0] == 0.0 and g[-1] == pytest.approx(1.2) and len(g) == 13
    for bad in (0.0, -0.1, math.nan, math.inf):
        with pytest.raises(ValueError, match="pressure step"):
            pressure_grid(bad)


def test_compute_curve_rejects_bad_grids():
    spec = CurveSpec("x", "free")
    for bad in ([0.1, 0.2], [0.0], [0.0, 0.2, 0.1]):
        with pytest.raises(ValueError, match="increasing"):
            compute_curve(spec, np.array(bad))


def test_table_round_trip(tmp_path):
    spec = CurveSpec("x", "k~ = 1e-4", ActuatorParams(gent_limit=15.0), 1e-4, sweep="object_stiffness",
                     sweep_value=1e-4)
    t = compute_curve(spec, pressure_grid(0.05))
    write_table(t, tmp_path / "x.csv")
    r = read_table(tmp_path / "x.csv")
    assert list(r.columns) == list(t.columns)
    for name in t.columns:
        if t[name].dtype.kind == "f":
            np.testing.assert_allclose(r[name], t[name], rtol=1e-9, atol=0, equal_nan=True)
        else:
            assert r[name].tolist() == t[name].tolist(), name


def test_a_failed_write_leaves_the_old_csv_and_png_whole(tmp_path, monkeypatch):
    """The CSV and the PNG are written atomically: a failure half-way (here the final rename) leaves the files as
    they were and no temporary file (the CSV used to be written in place)."""
    import os

    import matplotlib.pyplot as plt

    from pneunet_env.paper import plots

    table = linear_rows(ActuatorParams(), pressure_grid(0.1))  # closed form: no solve
    csv, png = tmp_path / "supp_fig3.csv", tmp_path / "supp_fig3.png"
    csv.write_text("old csv\n")
    png.write_bytes(b"old png")

    def fail(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="disk full"):
        write_table(table, csv)
    fig = plt.figure(figsize=(2, 2))
    with pytest.raises(OSError, match="disk full"):
        plots._finish(fig, png, "a note")  # every plot_* ends here
    assert csv.read_text() == "old csv\n" and png.read_bytes() == b"old png"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["supp_fig3.csv", "supp_fig3.png"]
    assert not plt.fignum_exists(fig.number)  # the figure is closed even when its save failed


@pytest.mark.parametrize("name", ["figures", "tables", "data", "plots", "checks", "checks_common", "checks_grasp",
                                  "checks_design"])
def test_paper_modules_are_sized_by_concern_and_write_no_file_in_place(name):
    path = Path(paper.__file__).parent / f"{name}.py"
    assert len(path.read_text().splitlines()) <= 800, name
    writes = [ast.unparse(node.func) for node in ast.walk(ast.parse(path.read_text()))
              if isinstance(node, ast.Call) and (
                  (isinstance(node.func, ast.Attribute) and node.func.attr in ("savefig", "write_text", "write_bytes"))
                  or (isinstance(node.func, ast.Name) and node.func.id == "open"
                      and any(isinstance(a, ast.Constant) and "w" in str(a.value) for a in node.args[1:2])))]
    assert not writes, (name, writes)  # CSVs through pneunet_env.files.atomic_write_text, PNGs through save_figure


def test_the_paper_modules_draw_their_bars_with_the_progress_helper():
    """No module of ``pneunet_env.paper`` imports tqdm: the figures' bar is ``pneunet_env.progress``'s."""
    for path in sorted(Path(paper.__file__).parent.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not any(n.split(".")[0] == "tqdm" for n in names), path.name


def test_intermediate_object_snaps_with_hysteresis():
    """Fig. 2's k~ = 1e-4: a fold on loading, one on unloading at a lower pressure, the window in between."""
    spec = CurveSpec("x", "k", ActuatorParams(gent_limit=15.0), 1e-4)
    t = compute_curve(spec, pressure_grid(0.01))
    lo, un = loading(t), unloading(t)
    up = lo["pressure"][lo["snapped"]]
    down = un["pressure"][un["snapped"]]
    assert up.size == 1 and down.size == 1 and down[0] < up[0]
    assert 0.6 < up[0] < 0.8
    # Inside the window the branches differ and the states are labelled snap-through; outside they agree.
    window = (lo["pressure"] > down[0] + 1e-9) & (lo["pressure"] < up[0] - 1e-9)
    assert np.all(np.abs(lo["curvature"] - un["curvature"])[window] > 1e-3)
    assert np.all(lo["regime"][window] == "snap-through")
    outside = ~window
    np.testing.assert_allclose(lo["curvature"][outside], un["curvature"][outside], atol=1e-8)
    # Before the fold the object holds the actuator (position control); long after, the force saturates.
    assert "position-controlled" in set(lo["regime"][lo["pressure"] < 0.5].tolist())
    assert lo["regime"][-1] == "force-controlled"


def test_free_curve_is_reversible_and_tangent_is_exact():
    t = compute_curve(CurveSpec("x", "free"), pressure_grid(0.01))
    lo, un = loading(t), unloading(t)
    np.testing.assert_allclose(lo["curvature"], un["curvature"], atol=1e-9)
    assert set(lo["regime"].tolist()) == {"free"} and not lo["snapped"].any()
    # The exact path tangent agrees with a central difference of the path.
    fd = np.gradient(lo["curvature"], lo["pressure"])
    i = slice(5, 40)
    np.testing.assert_allclose(lo["dcurvature_dpressure"][i], fd[i], rtol=2e-3)
    assert lo["dcurvature_dpressure"][0] == pytest.approx(ActuatorParams().small_pressure_slope, rel=1e-12)


def _classify(**kw):
    base = dict(pressure=[0.5], curvature=[0.03], contact_force=[1e-4], dcurvature_dpressure=[0.0],
                dforce_dpressure=[0.0], in_contact=[True], snapped=[False], bistable=[False])
    base.update({k: [v] for k, v in kw.items()})
    return classify_regimes(**{k: np.array(v) for k, v in base.items()})[0]


def test_classify_regimes_each_class():
    assert _classify(in_contact=False, snapped=True) == "free"
    assert _classify(snapped=True) == "snap-through"
    assert _classify(bistable=True, dcurvature_dpressure=0.0) == "snap-through"
    # elasticity of kappa: 0.5 * 0.006 / 0.03 = 0.1 <= 0.2
    assert _classify(dcurvature_dpressure=0.006, dforce_dpressure=1.0) == "position-controlled"
    # kappa elasticity 0.5 * 1 / 0.03 = 16.7; force elasticity 0.5 * 2e-5 / 1e-4 = 0.1
    assert _classify(dcurvature_dpressure=1.0, dforce_dpressure=2e-5) == "force-controlled"
    assert _classify(dcurvature_dpressure=1.0, dforce_dpressure=1e-3) == "transition"
    assert set(REGIMES) == {"free", "position-controlled", "force-controlled", "snap-through", "transition"}


def _curve(p, k, dk, snapped=None):
    n = len(p)
    return Table({"pressure": np.asarray(p, float), "curvature": np.asarray(k, float),
                  "dcurvature_dpressure": np.asarray(dk, float),
                  "snapped": np.zeros(n, bool) if snapped is None else np.asarray(snapped, bool)})


def test_critical_pressure_refines_the_peak_and_reports_snaps():
    p = np.linspace(0.0, 1.0, 11)
    dk = 2.0 - (p - 0.43) ** 2  # peak at 0.43, between grid points
    pc, smax = critical_pressure(_curve(p, np.zeros(11), dk))
    assert pc == pytest.approx(0.43, abs=1e-12) and smax == pytest.approx(2.0, abs=1e-12)
    sn = np.zeros(11, bool)
    sn[6] = True
    pc, smax = critical_pressure(_curve(p, np.zeros(11), dk, sn))
    assert pc == pytest.approx(0.5) and math.isinf(smax)


def test_linear_rows_follow_eq_17_and_stop_where_the_quadratic_energy_does():
    from pneunet_env.physics.linear import LinearModel

    params = ActuatorParams()
    ps = np.linspace(0.0, 3.0, 301)
    t = linear_rows(params, ps)
    assert set(t["model"].tolist()) == {"quadratic"}
    assert t["pressure"].max() < LinearModel(params).valid_until <= 3.0
    assert t["curvature"][1] / t["pressure"][1] == pytest.approx(params.small_pressure_slope, rel=2e-2)
    assert np.all(np.isfinite(t["curvature"]))


def test_figures_module_imports_without_matplotlib():
    code = ("import sys, pneunet_env.paper, pneunet_env.paper.figures, pneunet_env.paper.checks, "
            "pneunet_env.paper.command; assert 'matplotlib' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def _paper_imports() -> dict[str, set[str]]:
    """Module -> the ``pneunet_env.paper`` modules it imports anywhere in its source (lazy imports included)."""
    package = Path(paper.__file__).parent
    graph: dict[str, set[str]] = {}
    for path in sorted(package.glob("*.py")):
        name = path.stem
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module == "pneunet_env.paper":
                deps |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("pneunet_env.paper."):
                deps.add(node.module.removeprefix("pneunet_env.paper."))
            elif isinstance(node, ast.Import):
                deps |= {a.name.removeprefix("pneunet_env.paper.") for a in node.names
                         if a.name.startswith("pneunet_env.paper.")}
        graph[name] = deps - {name}
    return graph


def test_paper_import_graph_is_acyclic():
    graph = _paper_imports()
    # the layers, bottom up: the tables (CSV); the curves' data; the plots; the figures' registry and driver; the
    # statements (shared helpers, then by section, then the list); the command line on top
    assert graph["tables"] == set() and graph["data"] == {"tables"} and graph["plots"] == {"data", "tables"}
    assert graph["figures"] == {"data", "plots", "tables"}
    assert graph["checks_common"] == {"data", "tables"}
    assert graph["checks_grasp"] == graph["checks_design"] == {"checks_common", "data", "tables"}
    assert graph["checks"] == {"checks_common", "checks_grasp", "checks_design", "figures"}
    assert graph["command"] == {"figures", "checks"} and graph["__init__"] == set()
    assert graph["anchor"] == set()  # the experimental anchor: the physics alone, beside the figures
    assert set(graph) == {"__init__", "tables", "data", "plots", "figures", "checks_common", "checks_grasp",
                          "checks_design", "checks", "command", "anchor"}
    done: set[str] = set()

    def visit(node: str, stack: tuple[str, ...]) -> None:
        assert node not in stack, f"import cycle: {' -> '.join(stack + (node,))}"
        if node not in done:
            for dep in graph.get(node, ()):
                visit(dep, stack + (node,))
            done.add(node)

    for node in graph:
        visit(node, ())


def test_cli_figures_entry_is_the_command_module():
    module = importlib.import_module(cli.COMMANDS["figures"][0])
    assert module is command and callable(module.add_arguments) and callable(module.run)
