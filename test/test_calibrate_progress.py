"""``calibrate`` says how far it is at every FE solve, not only between explanations.

Off a terminal a plain line comes once ``PLAIN_EVERY_S`` have passed at the next progress call;
the calls came only at each explanation's start, and one explanation's fit is minutes of FE solves
(on the real pair lines came up to 118 s apart, where the README says every 30 s). Each FE solve
and each set of adjoint derivatives now reports the stage again (``SolutionStore.on_solve``), and
the surrogate's parameter sweeps report each solve (``compute_surrogate``).
"""

from __future__ import annotations

import itertools

from test_calibrate_twin import pair  # noqa: F401  (the twin before/after pair and its spec)


def test_the_forward_model_says_each_solve_and_each_set_of_derivatives() -> None:
    from bridge_shadow.calibrate.forward import ForwardModel, SolutionStore
    from bridge_shadow.model.config import load_bridge_config

    said: list[int] = []
    store = SolutionStore()
    store.on_solve = lambda: said.append(store.solves)
    fe = ForwardModel(load_bridge_config(), "coarse", ("slab_joint_opening",), store)
    fe.evaluate({"slab_joint_opening": 0.5})
    fe.evaluate({"slab_joint_opening": 0.5})  # cached: nothing solved, nothing said
    fe.evaluate({"slab_joint_opening": 0.25}, derivatives=False)
    assert store.solves == 2 and said == [1, 1, 2]  # solve, its derivatives, the second solve


def test_calibrate_reports_its_stage_at_every_solve(pair, monkeypatch) -> None:  # noqa: F811
    """The store ``calibrate`` shares between its explanations reports the stage it is in."""
    from bridge_shadow.calibrate import run
    from bridge_shadow.calibrate.spec import load_spec

    real = run.fit_explanation

    def fit(name, names, cfg, level, pairs, store=None, **kw):  # five FE solves' worth of reports
        for _ in range(5):
            store.solved()
        return real(name, names, cfg, level, pairs, store, **kw)

    monkeypatch.setattr(run, "fit_explanation", fit)
    calls: list[tuple[float, str]] = []
    run.calibrate(load_spec(pair["spec"]), only=["as_built"], report=lambda f, s: calls.append((f, s)))
    stage = [c for c in calls if c[1] == "explanation as_built"]
    assert len(stage) >= 6  # its start and each solve
    fractions = [c[0] for c in calls]
    assert all(b >= a for a, b in itertools.pairwise(fractions)) and fractions[-1] <= 1.0


def test_the_surrogates_sweeps_report_each_solve(monkeypatch) -> None:
    """``compute_surrogate`` hands its progress to the sweeps (about 20 FE solves said as one step)."""
    from bridge_shadow.model import surrogate
    from bridge_shadow.model.config import load_bridge_config

    def sweeps(cfg, level, base=None, report=None):  # the sweeps' own solves are tested elsewhere
        for k in range(4):
            report(k / 4, f"sweep {k}")
        return {}

    monkeypatch.setattr(surrogate, "compute_sweeps", sweeps)
    calls: list[tuple[float, str]] = []
    cfg = load_bridge_config()
    surrogate.compute_surrogate(
        cfg, "coarse", sensitivities=False, sweeps=True, report=lambda f, s: calls.append((f, s))
    )
    said = [c for c in calls if c[1].startswith("sweep ")]
    assert [c[1] for c in said] == ["sweep 0", "sweep 1", "sweep 2", "sweep 3"]
    fractions = [c[0] for c in calls]
    assert all(b >= a for a, b in itertools.pairwise(fractions)) and fractions[-1] == 1.0
