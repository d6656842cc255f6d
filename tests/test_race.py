"""The race of the starts (lpvid.initial.race): ranking, rounds, merged fits."""

import math
from dataclasses import replace

import numpy as np
import pytest

import lpvid
from lpvid.fit.judge import noise_slack
from lpvid.initial.race import Runner, Stage, _rank, merge, race
from lpvid.testing import noisy_data

BASIS = lpvid.Polynomial(2, domain=(0.0, 1.0))
FREQS = np.linspace(0.01, 0.45, 40)
POINTS = [0.0, 1.0]  # between them, 0.5 is where a bump of A(p) shows


def first_order(a) -> lpvid.LpvModel:
    """x+ = A(p) x + u, y = x: ``a(p)`` given as a function, quadratic in p."""
    p = np.array([0.0, 0.5, 1.0])
    rows = np.column_stack([np.ones(3), BASIS(p)])
    coef = np.linalg.solve(rows, a(p))
    zeros = [[[0.0]]] * 2
    return lpvid.LpvModel(
        [[[c]] for c in coef], [[[1.0]], *zeros], [[[1.0]], *zeros], basis=BASIS, Ts=1.0
    )


@pytest.fixture(scope="module")
def case():
    """Data at p = 0 and 1 from A(p) = 0.5 + 0.002 p, validation at 0.25, 0.5, 0.75; the runners.

    - ``simple``: A = 0.5 (no scheduling dependence), within the noise of the truth;
    - ``truth``;
    - ``far``: A = 0.5 + 0.1 p, stable, far above the others;
    - ``bump``: the truth plus 4 p (1 - p): the same frozen models at the
      points (the same identification V_NLS as the truth), unstable at 0.5.
    """
    truth = first_order(lambda p: 0.5 + 0.002 * p)
    rng = np.random.default_rng(0)
    data = noisy_data(truth, POINTS, FREQS, rng, 0.01)
    validation = noisy_data(truth, [0.25, 0.5, 0.75], FREQS, rng, 0.01)
    models = {
        "far": first_order(lambda p: 0.5 + 0.1 * p),
        "bump": first_order(lambda p: 0.5 + 0.002 * p + 4 * p * (1 - p)),
        "truth": truth,
        "simple": first_order(lambda p: 0.5 + 0 * p),
    }
    runners = [_runner(name, m) for name, m in models.items()]
    return data, validation, runners


def _runner(name, model, **options) -> Runner:
    """A runner of one stage, every parameter free."""
    return Runner(name, model, [Stage("all groups", np.zeros(model.theta.size, bool))], **options)


def _order(runners, keys):
    return [runners[k[-1]].name for k in sorted(keys)]


def test_the_case_is_what_it_says(case):
    data, _, runners = case
    cost = {r.name: lpvid.vnls(r.model, data) for r in runners}
    assert cost["bump"] == pytest.approx(cost["truth"], rel=1e-9)
    assert cost["bump"] < cost["far"] / 10
    assert 0 < cost["simple"] - cost["truth"] < noise_slack(data.n_residuals)


def test_stable_runners_first_then_ties_by_simplicity_without_validation(case):
    """Costs are identification V_NLS; the tie within the noise goes to the simpler."""
    data, _, runners = case
    keys = _rank(runners, data, None)
    assert _order(runners, keys) == ["simple", "truth", "far", "bump"]
    by_name = {r.name: k for r, k in zip(runners, keys, strict=True)}
    assert [by_name[n][0] for n in ("simple", "truth", "far", "bump")] == [0, 0, 0, 1]
    assert not by_name["simple"][1] and not by_name["truth"][1] and by_name["far"][1]
    assert by_name["bump"][1]  # its cost ties the best, but only stable runners tie
    for r, k in zip(runners, keys, strict=True):
        assert k[3] == lpvid.vnls(r.model, data) and k[-1] == runners.index(r)


def test_with_validation_data_the_costs_are_validation_costs(case):
    data, validation, runners = case
    keys = _rank(runners, data, validation)
    assert _order(runners, keys) == ["simple", "truth", "far", "bump"]
    for r, k in zip(runners, keys, strict=True):
        assert k[3] == lpvid.vnls(r.model, validation)


def test_when_every_runner_is_unstable_the_ties_come_from_all_costs(case):
    """No stable runner: the tie and its simplest are found among all (none left out)."""
    data, _, runners = case
    bump = runners[1]
    keys = _rank([bump], data, None)
    assert keys[0][:2] == (True, False)  # unstable, and the best of one ties with itself


def test_the_race_drops_the_worse_half_and_refines_the_rest_to_the_end(case):
    """Six starts, two rounds of 2 steps: half leave after each, the rest converge.

    Every runner either converged (not stopped by its step limit) or left
    the race at the end of a round with the steps it had then; those that
    left after the first round validated worse at that moment than every
    runner that went on (the starts' bumps between the points are largest
    where they fit the points best: by identification V_NLS the other half
    would have left); at least ``keep`` runners converged, some of them
    after the last round.
    """
    data, validation, _ = case
    starts = [
        first_order(lambda p, k=k: 0.502 + (0.4 - 0.07 * k) * p * (1 - p) + 0.02 * k)
        for k in range(6)
    ]
    runners = [_runner(f"s{k}", m, ftol=0.0) for k, m in enumerate(starts)]
    seen = {}  # (name, steps) -> (validation, identification V_NLS) after each round

    def step(r):
        seen[r.name, r.steps] = (lpvid.vnls(r.model, validation), lpvid.vnls(r.model, data))

    assert race(runners, data, validation, rounds=(2, 2), keep=2, step=step) == runners
    ends = {2, 4}  # steps at the end of the first and the second round
    for r in runners:
        assert r.steps == len(r.fit.history)  # one stage: every step is in its history
        if r.dropped is None:
            assert r.done and r.fit.stop != "max_iterations", r.name
        else:
            assert not r.done and r.dropped == r.steps and r.dropped in ends, r.name
    assert sum(r.done for r in runners) >= 2 and max(r.steps for r in runners) > max(ends)
    left = [r.name for r in runners if r.dropped == 2]
    went_on = [r.name for r in runners if r.dropped != 2]
    assert len(left) == 3 and any(r.dropped == 4 for r in runners)  # and some after the second
    val = {name: v[0] for (name, n), v in seen.items() if n == 2}
    ident = {name: v[1] for (name, n), v in seen.items() if n == 2}
    assert max(val[n] for n in went_on) < min(val[n] for n in left)
    assert max(ident[n] for n in went_on) > min(ident[n] for n in left)


def test_a_runner_dropped_between_its_stages_leaves_with_a_fit_of_no_step(case):
    """``far`` in two stages of two steps: the round's budget ends its first, and it is dropped.

    It is then between stages, with no fit of the second: it leaves with a
    fit of no step at the model the first ended on (before, its fit was
    None and the candidate built from it failed an assertion in identify).
    """
    data, validation, runners = case
    free = np.zeros(runners[0].model.theta.size, bool)
    entered = [_runner(r.name, r.model) for r in runners if r.name != "far"]
    far_model = next(r.model for r in runners if r.name == "far")
    far = Runner("far", far_model, [Stage("first", free), Stage("second", free)], 2, ftol=0.0)
    race([*entered, far], data, validation, rounds=(2,), keep=2)
    assert far.dropped == 2 and far.history[0]["n_iter"] == 2 and not far.done
    fit = far.fit
    assert fit is not None and fit.stop == "dropped" and fit.n_iter == 0
    assert fit.model is far.model and fit.vnls == far.history[0]["vnls"]
    assert "before a step of stage 2" in fit.message
    assert lpvid.vnls(far.model, data) == pytest.approx(fit.vnls, rel=1e-12)


def test_two_runs_merge_into_one(case):
    """A runner's fit over several rounds: one history, its sums, the last run's model."""
    data, _, runners = case
    start = runners[0].model  # far from the optimum: steps to take
    a = lpvid.fit_nls(start, data, max_iter=2, warn=False)
    b = lpvid.fit_nls(a.model, data, max_iter=3, warn=False)
    # This convex case rejects no step: counts of their own, to see them add up.
    a, b = replace(a, n_rejected=2), replace(b, n_rejected=3)
    m = merge(a, b)
    assert merge(None, b) is b
    assert m.history == a.history + b.history
    assert m.model is b.model and m.vnls == b.vnls and m.objective == b.objective
    assert m.noise_floor == b.noise_floor and m.converged == b.converged
    assert m.stop == b.stop and m.message == b.message and m.interrupted == b.interrupted
    assert m.n_rejected == a.n_rejected + b.n_rejected
    assert m.timings["total_s"] == a.timings["total_s"] + b.timings["total_s"]
    lm = [r["seconds"] for r in m.history]
    assert m.timings["lm_iter_s"] == pytest.approx(np.mean(lm), rel=1e-12)
    assert np.isnan(m.timings["socp_iter_s"])


def test_a_race_whose_runners_all_converge_in_a_round_drops_none(case):
    data, validation, runners = case
    fresh = [_runner(r.name, r.model) for r in runners]
    assert race(fresh, data, validation, rounds=(100, 100)) == fresh
    assert all(r.done and r.dropped is None for r in fresh)


def test_a_hopeless_start_leaves_without_a_step_and_says_why(case, monkeypatch):
    """Far above the best start (HOPELESS lowered to make ``far`` so): no step, its start kept.

    The others race as they do with ``far`` in the race (the hopeless
    count in the first round's halving): no runner's fit changes. ``far``
    is entered last, so that every runner before it is looked at too, and
    a start whose V_NLS is not finite leaves the same way.
    """
    from lpvid.initial import race as race_module

    data, validation, runners = case
    cost = {r.name: lpvid.vnls(r.model, data) for r in runners}
    ratio = cost["far"] / min(cost.values())
    assert ratio > 10
    order = sorted(runners, key=lambda r: r.name == "far")  # far last

    def fresh():
        out = [_runner(r.name, r.model) for r in order]
        broken = _runner("broken", order[0].model)
        broken.fit = race_module._unfitted(broken.model, math.inf, data, "as given")
        return [broken, *out]

    before = race(fresh(), data, validation, rounds=(2,))
    monkeypatch.setattr(race_module, "HOPELESS", ratio / 2)
    seen = []
    after = race(fresh(), data, validation, rounds=(2,), step=seen.append)
    far, broken = after[-1], after[0]
    assert far.name == "far" and far.dropped == 0 and far.steps == 0 and far.fit.n_iter == 0
    assert seen[:2] == [broken, far]  # the hopeless, reported as they leave
    fit = far.fit
    assert fit.stop == "dropped" and fit.converged is False and fit.interrupted is False
    assert fit.model is far.model and fit.vnls == fit.objective == cost["far"]
    assert fit.noise_floor == data.n_residuals and fit.n_rejected == 0
    assert fit.timings.keys() == after[1].fit.timings.keys() and fit.timings["total_s"] == 0
    assert f"{ratio / 2:g} times the best start's" in fit.message
    assert broken.dropped == 0 and "not finite" in broken.fit.message
    # With no start of finite V_NLS there is nothing to be far above: none leaves so.
    alone = race(fresh()[:1], data, validation, rounds=(2,))
    assert alone[0].dropped is None and alone[0].steps > 0
    for a, b in zip(before, after, strict=True):
        if a.name not in ("far", "broken"):
            assert (a.dropped is None) == (b.dropped is None)
            assert np.array_equal(a.model.theta, b.model.theta)
