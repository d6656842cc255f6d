"""Initial estimates that survive poorly determined local models (lpvid.initial)."""

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment
from systems import (
    GANTRY_FREQS,
    GANTRY_P,
    gantry_like,
    heavily_damped,
    lti_frf,
    modal_system,
    scramble,
)

import lpvid
from lpvid import initial
from lpvid.data.schedule import between_points
from lpvid.fit.settings import START_FTOL
from lpvid.model.frozen import frozen_stable

# ------------------------------------------------------------------ helpers
DAMPED_FREQS = np.logspace(np.log10(2.0), np.log10(300.0), 150)
DAMPED_P = np.linspace(0.0, 1.0, 5)
DAMPED_MID = (DAMPED_P[1:] + DAMPED_P[:-1]) / 2
DAMPED_BASIS = lpvid.Polynomial(1, domain=(0.0, 1.0))


def frf_data(system, p, freqs, seed, rel=0.01):
    """FRFs of system(p) at the points, with complex noise of 1 % of |G| (known sigma)."""
    rng = np.random.default_rng(seed)
    z = 2j * np.pi * freqs
    G = np.array([lti_frf(system(s), z) for s in p])
    sigma = rel * np.abs(G)
    G = G + sigma * (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
    return lpvid.FrfData(p, freqs, G, sigma)


@pytest.fixture(scope="module")
def hard():
    """Identification data at 5 points and validation data at the 4 midpoints.

    The noise seed is one for which the plain route fails (over 20 seeds it
    failed on 7, and the robust route reached the floor on all 20).
    """
    return frf_data(heavily_damped, DAMPED_P, DAMPED_FREQS, 6), frf_data(
        heavily_damped, DAMPED_MID, DAMPED_FREQS, 106
    )


def lti(model, Ts=None):
    return lpvid.LpvModel(*model, Ts=Ts)


def three_modes(s, shift=None):
    """A smooth SIMO system with three light modes; ``shift`` = (mode, factor) moves one."""
    freqs = [20.0 + 5.0 * s, 60.0 - 8.0 * s, 150.0 + 20.0 * s]
    if shift is not None:
        freqs[shift[0]] *= shift[1]
    return modal_system(
        freqs,
        [0.02, 0.03 + 0.01 * s, 0.02],
        [np.array([[1.0], [0.3]]), np.array([[0.8], [-0.2]]), np.array([[0.5], [0.4]])],
        [
            np.array([[1.0, 0.2], [0.1, 0.5]]),
            np.array([[0.5, -0.4], [0.3, 0.2]]),
            np.array([[0.3, 1.0], [0.5, 0.1]]),
        ],
        np.zeros((2, 1)),
    )


# ------------------------------------------------------------------ diagnosis
def test_consistency_passes_the_gantry_like_local_models(rng):
    locs = [lti(scramble(gantry_like(q), rng)) for q in GANTRY_P]
    diag = initial.consistency(locs, GANTRY_P)
    assert diag.ok and diag.inconsistent == []
    assert np.all(diag.scores < 2.0)
    assert "consistent" in str(diag) and "inconsistent" not in str(diag)


@pytest.mark.parametrize("q", [0, 2, 4])
def test_consistency_flags_a_pole_moved_by_a_large_factor(rng, q):
    p = np.linspace(0.0, 1.0, 5)
    locs = [
        lti(scramble(three_modes(s, (1, 30.0) if k == q else None), rng)) for k, s in enumerate(p)
    ]
    diag = initial.consistency(locs, p)
    assert diag.inconsistent == [q]
    assert not diag.ok and diag.worst == q
    # The score of the odd point is far above the others'.
    others = np.delete(diag.scores, q)
    assert diag.scores[q] > 10 * others.max()
    text = str(diag)
    assert f"inconsistent at point(s) [{q}]" in text and "Hz" in text


def test_consistency_flags_a_pair_split_into_real_poles():
    p = np.linspace(0.0, 1.0, 5)
    locs = [lti(three_modes(s)) for s in p]
    # At point 3 the 60 Hz pair becomes two real poles at nearly the same frequency.
    A, B, C, D = three_modes(p[3])
    w = np.abs(np.linalg.eigvals(A[2:4, 2:4]))[0]
    A = A.copy()
    A[2:4, 2:4] = np.diag([-0.8 * w, -1.2 * w])
    locs[3] = lti((A, B, C, D))
    diag = initial.consistency(locs, p)
    assert diag.inconsistent == [3]
    assert "real pole" in diag.details[3]


def test_consistency_with_two_scheduling_parameters(rng):
    g = np.linspace(0.0, 1.0, 3)
    p = np.array([[a, b] for a in g for b in g])

    def system(pq, odd=False):
        s = 0.5 * (pq[0] + pq[1] ** 2)
        return three_modes(s, (2, 0.05) if odd else None)

    good = [lti(system(pq)) for pq in p]
    assert initial.consistency(good, p).ok
    for q in (4, 0):
        locs = [lti(scramble(system(pq, k == q), rng)) for k, pq in enumerate(p)]
        assert initial.consistency(locs, p).inconsistent == [q]


def test_consistency_rejects_bad_input():
    m = lti(three_modes(0.0))
    with pytest.raises(ValueError, match=r"^local_models: needs at least 2 model\(s\), got 1"):
        initial.consistency([m], [0.0])
    with pytest.raises(ValueError, match=r"^p: 2 scheduling values for 3 models"):
        initial.consistency([m, m, m], [0.0, 1.0])
    with pytest.raises(ValueError, match=r"^p: required unless local_models is a LocalModels"):
        initial.consistency([m, m], None)
    with pytest.raises(ValueError, match=r"^p: scheduling values must be distinct"):
        initial.consistency([m, m], [1.0, 1.0])
    with pytest.raises(
        TypeError, match=r"^local_models: expected LocalModels or a list of LTI LpvModel"
    ):
        initial.consistency(m, [0.0])


# ------------------------------------------------------------------ pole uncertainty
def test_pole_uncertainty_matches_the_scatter_of_refitted_poles():
    # A SISO system with one light and one heavy mode; refit 60 noise realisations.
    true = modal_system(
        [10.0, 30.0],
        [0.05, 0.5],
        [np.array([[1.0], [0.3]]), np.array([[0.6], [-0.4]])],
        [np.array([[1.0, 0.2]]), np.array([[0.5, 0.7]])],
        np.zeros((1, 1)),
    )
    freqs = np.linspace(2.0, 80.0, 60)
    G = lti_frf(true, 2j * np.pi * freqs)[None]
    sigma = 0.02 * np.abs(G)
    model = lti(true)
    ref = initial.pole_coordinates(model)
    rng = np.random.default_rng(7)
    devs = []
    for _ in range(60):
        noise = sigma * (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
        data = lpvid.FrfData([0.0], freqs, G + noise, sigma)
        fit = lpvid.fit_nls(model, data)
        u = initial.pole_coordinates(fit.model)
        rows, cols = linear_sum_assignment(np.abs(ref[:, None] - u[None, :]))
        devs.append(u[cols[np.argsort(rows)]] - ref)
    devs = np.array(devs)
    scatter = np.sqrt(np.mean(np.abs(devs - devs.mean(axis=0)) ** 2, axis=0))
    predicted = initial.pole_uncertainty(model, lpvid.FrfData([0.0], freqs, G, sigma))
    order = np.argsort(np.abs(np.linalg.eigvals(true[0])))
    ratio = predicted / scatter
    assert np.all((ratio > 0.75) & (ratio < 1.33)), ratio
    # The heavy mode is known less well than the light one.
    assert predicted[order[-1]] > 3 * predicted[order[0]]


# ------------------------------------------------------------------ continuation walk
def test_continuation_order_walks_outwards_along_the_sorted_points():
    p = np.array([0.3, 0.0, 0.1, 0.4, 0.2])
    order, parent = initial.continuation_order(p, root=2)  # root at p = 0.1
    assert order[0] == 2 and parent[2] == -1
    assert sorted(order) == list(range(5))
    rank = np.argsort(np.argsort(p))  # position of each point along the axis
    seen = {2}
    for q in order[1:]:
        assert parent[q] in seen  # started from a point already identified
        assert abs(rank[q] - rank[parent[q]]) == 1  # its neighbour on the axis
        assert abs(rank[q] - rank[2]) > abs(rank[parent[q]] - rank[2])  # outwards
        seen.add(q)


def test_continuation_order_follows_a_nearest_neighbour_tree_in_two_parameters():
    # A 3 x 4 grid with unequal spacing in the two parameters (scaled to [0, 1] each).
    p = np.array([[a, b] for a in (0.0, 5.0, 10.0) for b in (0.0, 0.1, 0.2, 0.3)])
    order, parent = initial.continuation_order(p, root=11)
    assert order[0] == 11 and sorted(order) == list(range(12))
    s = (p - p.min(axis=0)) / np.ptp(p, axis=0)
    seen = {11}
    for q in order[1:]:
        assert parent[q] in seen
        step = np.abs(s[q] - s[parent[q]])
        # One grid step along one parameter: the nearest neighbours.
        assert np.count_nonzero(step > 1e-12) == 1
        assert np.isclose(step.max(), 1 / 3) or np.isclose(step.max(), 1 / 2)
        seen.add(q)
    with pytest.raises(ValueError, match=r"^root: expected a point index in 0\.\.11, got 12"):
        initial.continuation_order(p, root=12)


def test_the_continuation_walks_the_subtrees_below_the_root_apart():
    """Every point once, each subtree below a neighbour of the root in its walking order."""
    from lpvid.data.schedule import subtrees

    p = np.array([0.3, 0.0, 0.1, 0.4, 0.2])
    order, parent = initial.continuation_order(p, root=2)  # root at p = 0.1
    assert subtrees(order, parent) == [[1], [4, 0, 3]]  # either side, in walking order
    assert subtrees(*initial.continuation_order(p, root=1)) == [[2, 4, 0, 3]]  # an end
    grid = np.array([[a, b] for a in (0.0, 5.0, 10.0) for b in (0.0, 0.1, 0.2, 0.3)])
    order, parent = initial.continuation_order(grid, root=5)
    walks = subtrees(order, parent)
    assert sorted(q for w in walks for q in w) == sorted(set(range(12)) - {5})
    assert len(walks) == int(np.sum(parent == 5)) >= 2
    for w in walks:
        assert parent[w[0]] == 5  # a neighbour of the root first
        position = {q: k for k, q in enumerate(w)}
        assert all(position[parent[q]] < k for k, q in enumerate(w[1:], 1))  # parent before


def test_best_determined_point_has_the_most_certain_poles(hard):
    data, _ = hard
    local = lpvid.identify_lti(data, 6)
    root = initial.best_determined(local, data)
    worst = [
        np.max(initial.pole_uncertainty(local[q], data.subset([q]))) for q in range(len(local))
    ]
    # At s = 0 the modes are the least damped: that end is the best determined.
    assert root == int(np.argmin(worst)) == 0


def test_best_determined_computes_each_points_poles_once_for_its_data(hard, monkeypatch):
    """Asked again (identify asks twice), the same answer without the pole uncertainties."""
    import lpvid.initial.continuation as continuation

    data, _ = hard
    local = lpvid.identify_lti(data, 6)
    calls = []
    real = continuation.pole_uncertainty

    def counted(model, point_data, fixed=None):
        calls.append(fixed)
        return real(model, point_data, fixed)

    monkeypatch.setattr(continuation, "pole_uncertainty", counted)
    first = initial.best_determined(local, data)
    asked = len(calls)
    assert asked >= 2
    assert initial.best_determined(local, data) == first and len(calls) == asked
    # other fixed parameters, or other data (a copy): computed anew
    initial.best_determined(local, data, fixed={"D": True})
    assert len(calls) == 2 * asked and calls[-1] == {"D": True}
    copy = data.subset(list(range(data.n_points)))
    assert initial.best_determined(local, copy) == first and len(calls) == 3 * asked


# ------------------------------------------------------------------ identify_lti(continuation=)
def test_identify_lti_continuation_keeps_the_local_models_on_one_branch(hard):
    data, _ = hard
    plain = lpvid.identify_lti(data, 6)
    assert plain.starts == ("plain",) * 5 and plain.consistency is None
    auto = lpvid.identify_lti(data, 6, continuation="auto")
    # The diagnosis flags the plain models (a damped pair split into real poles) ...
    assert not auto.consistency.ok
    assert any(s.startswith("continuation from") for s in auto.starts)
    # ... the continued models are consistent and each fits its point at the noise floor.
    assert initial.consistency(auto).ok
    assert np.all(auto.vnls / auto.noise_floor < 1.1)
    assert np.all(auto.vnls <= plain.vnls + np.sqrt(auto.noise_floor) + 1e-9)
    # The walk starts at the best-determined point and goes outwards.
    root = auto.starts.index("plain")
    assert root == initial.best_determined(plain, data)
    for q, s in enumerate(auto.starts):
        if s.startswith("continuation from"):
            assert abs(int(s.rsplit(" ", 1)[1]) - q) == 1
    forced = lpvid.identify_lti(data, 6, continuation=True)
    assert forced.starts == auto.starts
    with pytest.raises(
        ValueError, match=r"^continuation: expected True, False or 'auto', got 'always'"
    ):
        lpvid.identify_lti(data, 6, continuation="always")


def test_identify_lti_auto_leaves_consistent_models_alone():
    z = 2j * np.pi * GANTRY_FREQS
    G = np.array([lti_frf(gantry_like(q), z) for q in GANTRY_P])
    sigma = 1e-3 * np.abs(G) + 1e-9
    rng = np.random.default_rng(3)
    noise = sigma * (rng.normal(size=G.shape) + 1j * rng.normal(size=G.shape)) / np.sqrt(2)
    data = lpvid.FrfData(GANTRY_P, GANTRY_FREQS, G + noise, sigma)
    local = lpvid.identify_lti(data, 6, continuation="auto")
    assert local.consistency is not None and local.consistency.ok
    assert local.starts == ("plain",) * 5


# ------------------------------------------------------------------ global start
def test_global_start_frees_the_groups_in_stages(hard):
    data, _ = hard
    basis = lpvid.Polynomial(2, domain=(0.0, 1.0))
    local = lpvid.identify_lti(data, 6)
    m = initial.global_start(data, 6, basis, local=local, stages="degree")
    hist = m.info["history"]
    assert m.info["method"] == "global_start" and m.info["stages"] == "degree"
    assert [h["free_groups"] for h in hist] == ["constant only", "degree <= 1", "degree <= 2"]
    v = [h["vnls"] for h in hist]
    assert v[0] > 5 * data.n_residuals  # a constant model cannot fit these data
    assert v[1] <= v[0] and v[2] <= v[1] * (1 + 1e-9)
    assert v[2] < 1.1 * data.n_residuals
    assert np.isclose(lpvid.vnls(m, data), v[2])
    assert m.info["point"] == initial.best_determined(local, data)
    one = initial.global_start(data, 6, basis, local=local, stages="all", point=2)
    assert [h["free_groups"] for h in one.info["history"]] == ["constant only", "degree <= 2"]
    assert one.info["point"] == 2
    with pytest.raises(
        ValueError, match=r"^stages: expected one of \('all', 'degree'\), got 'one'"
    ):
        initial.global_start(data, 6, basis, local=local, stages="one")


def test_global_start_keeps_fixed_parameters():
    A, B, C, D = three_modes(0.3)
    p = np.linspace(0.0, 1.0, 3)
    freqs = np.linspace(5.0, 250.0, 80)
    G = np.array([lti_frf(three_modes(s), 2j * np.pi * freqs) for s in p])
    data = lpvid.FrfData(p, freqs, G, 1e-3 * np.abs(G) + 1e-9)
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    m = initial.global_start(data, 6, basis, fixed={"D": True, "B": [1]})
    assert np.all(m.D == 0.0) and np.all(m.B[1] == 0.0)


# ------------------------------------------------------------------ the hard case
def test_hard_case_plain_route_stalls_and_the_robust_route_reaches_the_noise_floor(hard):
    data, val = hard
    M, Mv = data.n_residuals, val.n_residuals
    # The plain route, independently: local models, every SMILE form, fit_nls.
    local = lpvid.identify_lti(data, 6)
    plain = {
        form: lpvid.fit_nls(m0, data, warn=False)  # it stalls: that is the point
        for form, m0 in lpvid.smile_candidates(local, basis=DAMPED_BASIS).items()
    }
    assert plain, "no coherent form could be built"
    assert min(f.vnls for f in plain.values()) > 1.5 * M  # far above the noise floor
    assert min(lpvid.vnls(f.model, val) for f in plain.values()) > 1.5 * Mv

    cands = initial.initial_candidates(data, 6, DAMPED_BASIS, validation=val, local=local)
    names = [c.name for c in cands]
    assert {f"smile:{k}" for k in plain} <= set(names)
    assert "global:all" in names and any(n.startswith("continuation+smile:") for n in names)
    for c in cands:
        assert np.isclose(c.vnls, lpvid.vnls(c.model, data))
        assert np.isclose(c.validation_vnls, lpvid.vnls(c.model, val))
        assert c.noise_floor == M and c.validation_floor == Mv and c.seconds >= 0
        assert c.fit is not None and np.isclose(c.fit.vnls, c.vnls) and c.fit.model is c.model
        assert c.start is not None and c.start.n_basis == 1
        if c.name.startswith(("smile:", "continuation+smile:")):
            assert c.start.info["form"] == c.name.rsplit(":", 1)[1]
        else:  # the last stage of "global:all" starts from the constant model
            assert c.start.group_norms().count() == 0 and c.constant_groups == 0
    chosen, reason = initial.choose(cands)
    assert not chosen.name.startswith("smile:")
    assert chosen.vnls < 1.1 * M  # within 10 % of the noise floor
    assert chosen.validation_vnls < 1.3 * Mv  # within 30 % between the points
    assert "validation" in reason
    # Each robust route reaches it on its own.
    for prefix in ("continuation+smile:", "global:"):
        route = [c for c in cands if c.name.startswith(prefix)]
        best, _ = initial.choose(route)
        assert best.vnls < 1.1 * M and best.validation_vnls < 1.3 * Mv, prefix
    # The interpolated plain models go unstable between the points; the chosen one does not.
    between = between_points(data.p)
    assert chosen.stable and not any(frozen_stable(f.model, between) for f in plain.values())


def test_the_race_of_the_starts_keeps_the_choice_of_full_refinement(hard):
    """Successive halving refines fewer starts and picks what refining all would.

    "What": a model that ``choose`` counts as equal to the pick of full
    refinement (as simple, validation V_NLS within its 2 % tolerance). On this
    case several continuation starts end at the noise floor within 0.5 % of
    each other in validation after LM runs cut at their iteration limit, so
    which of those equals carries the name depends on rounding: changing the
    order of the sums in the Gram matrix (same values to 1e-12) moved the
    full-refinement validation V_NLS of one start from 650 to 621.
    """
    data, val = hard
    local = lpvid.identify_lti(data, 6)
    kw = dict(validation=val, local=local)
    raced = initial.initial_candidates(data, 6, DAMPED_BASIS, **kw)
    full = initial.initial_candidates(data, 6, DAMPED_BASIS, halving=False, **kw)
    assert [c.name for c in raced] == [c.name for c in full]
    assert all(c.refined for c in full)
    dropped = [c for c in raced if not c.refined]
    assert dropped and all("dropped from the race" in c.note for c in dropped)
    steps = sum(len(c.fit.history) for c in raced)
    assert steps < 0.7 * sum(len(c.fit.history) for c in full)
    pick, _ = initial.choose(raced)
    want, _ = initial.choose(full)
    assert pick.refined and pick.stable
    # The race ranks its rounds as choose does (lpvid.fit.judge: within 2 % of the
    # best validation V_NLS the least scheduling dependence first), so the
    # pick is as simple as that of full refinement whatever the last bits.
    assert pick.dependence <= (1 + lpvid.fit.judge.DEPENDENCE_TIE) * want.dependence
    assert pick.validation_vnls <= 1.02 * want.validation_vnls
    assert pick.vnls <= 1.02 * want.vnls
    # The pick refined the same way in both routes ends where it did.
    same = next(c for c in full if c.name == pick.name)
    assert pick.validation_vnls == pytest.approx(same.validation_vnls, rel=0.02)


def test_the_race_stops_the_slide_and_keeps_the_choice_of_full_convergence(hard):
    """Fits that end when a step buys less than START_FTOL of V_NLS pick what full fits do.

    Every refined start ends by the cost rule (no step limit) at its first
    accepted step below ``START_FTOL V_NLS``, in fewer steps than the same
    race with an ``ftol`` of 1e-10, and lands within the noise of where those
    end.
    """
    data, val = hard
    local = lpvid.identify_lti(data, 6)
    kw = dict(validation=val, local=local)
    quick = initial.initial_candidates(data, 6, DAMPED_BASIS, **kw)
    slow = initial.initial_candidates(data, 6, DAMPED_BASIS, ftol=1e-10, **kw)
    ended = [c for c in quick if c.refined and c.fit.history and c.fit.history[-1]["accepted"]]
    assert ended and all(c.fit.stop == "cost_change" for c in ended)
    for c in ended:
        rows = [r["vnls"] for r in c.fit.history if r["accepted"]]
        assert len(rows) >= 2 and rows[-2] - rows[-1] <= START_FTOL * rows[-2]
        # ... and not later: every accepted step before it bought more.
        assert all(a - b > START_FTOL * a for a, b in zip(rows[:-2], rows[1:-1], strict=True))
    steps = sum(len(c.fit.history) for c in quick)
    assert steps < sum(len(c.fit.history) for c in slow)
    pick, _ = initial.choose(quick)
    want, _ = initial.choose(slow)
    # Issue 31: with numpy's OpenBLAS on its Haswell, Sandybridge or Nehalem
    # kernels the slow race once dropped a start 1.0001 x the best, when it
    # ranked its rounds by validation V_NLS alone; it ranks them as choose
    # does now (lpvid.fit.judge), and .ci/run runs this test on other numerics.
    assert pick.stable
    assert pick.dependence <= (1 + lpvid.fit.judge.DEPENDENCE_TIE) * want.dependence
    assert pick.validation_vnls <= 1.02 * want.validation_vnls
    assert pick.vnls <= want.vnls + 2 * np.sqrt(data.n_residuals)


def test_hopeless_starts_leave_without_a_step_and_the_race_goes_on_as_before(hard, monkeypatch):
    """Starts far above the best start take no step; the others race exactly as if they ran."""
    from lpvid.initial import race

    data, val = hard
    local = lpvid.identify_lti(data, 6)
    kw = dict(validation=val, local=local)
    limit = race.HOPELESS
    quick = initial.initial_candidates(data, 6, DAMPED_BASIS, **kw)
    monkeypatch.setattr(race, "HOPELESS", np.inf)
    full = initial.initial_candidates(data, 6, DAMPED_BASIS, **kw)
    # The models the runners started from ("global:all" starts from the constant model).
    start = {c.name: lpvid.vnls(c.start, data) for c in full if c.name != "global:degree"}
    none = [c for c in quick if not c.fit.history]
    assert none and all("after 0 steps" in c.note and not c.refined for c in none)
    assert all(start[c.name] > limit * min(start.values()) for c in none)
    # Each is its start, as it was: V_NLS and model.
    for c in none:
        assert c.fit.stop == "dropped" and not c.fit.converged
        assert c.vnls == start[c.name] and np.array_equal(c.model.theta, c.start.theta)
    for a, b in zip(quick, full, strict=True):
        assert a.name == b.name and a.refined == b.refined
        if a.refined:  # the same fit, to the last bit
            assert np.array_equal(a.model.theta, b.model.theta)
    assert sum(len(c.fit.history) for c in quick) < sum(len(c.fit.history) for c in full)


def test_a_runner_unstable_after_a_round_goes_on_while_it_is_in_the_better_half(hard, monkeypatch):
    """Unstable runners rank last in a round, but those in the better half go on.

    Where a start ends is not told by its stability after a few steps: on
    ``benches/bench_between.py``'s ``cross3`` seed 1 the winning start is
    unstable after the first round and stable, at a tenth of the others'
    validation V_NLS, after the second (dropping such runners was measured:
    see docs/performance.md). The hard case's runners are all stable; two
    that went past the first round are ranked unstable here: they fall to
    the end of the ranking, so the best runner left out before takes the
    place of one of them, while the other is still in the better half and
    goes on; every stable runner that went on before goes on again.

    The situation is built on purpose: the runners' fits end only at their
    step limit (no tolerance), so that none ends inside the first round and
    the runners past it are exactly the better half the race keeps, by the
    race's count alone. (With the starts' tolerance, whether a runner
    converged at the first round's last step followed numpy's BLAS kernel,
    and with it how many went on: issue 59.)
    """
    from lpvid.initial import race

    data, val = hard
    local = lpvid.identify_lti(data, 6)
    kw = dict(validation=val, local=local, ftol=0.0)

    def to_the_limit(*args, **kwargs):
        return lpvid.fit_nls(*args, **{**kwargs, "xtol": 0.0})

    monkeypatch.setattr(race, "fit_nls", to_the_limit)
    first = race.ROUNDS[0]
    plain = initial.initial_candidates(data, 6, DAMPED_BASIS, **kw)
    raced = [c.name for c in plain if c.fit.history]  # not dropped as hopeless
    went_on = [c.name for c in plain if len(c.fit.history) > first]
    # The race keeps the better half of every start that entered, hopeless ones counted.
    assert len(went_on) == max(2, -(-len(plain) // 2)) < len(raced)
    assert all(
        len(c.fit.history) == first for c in plain if c.name in raced and c.name not in went_on
    )
    marked = set(went_on[:2])
    rank = race._rank

    def marking(runners, data, validation):
        keys = rank(runners, data, validation)
        return [(k[0] or r.name in marked, *k[1:]) for r, k in zip(runners, keys, strict=True)]

    monkeypatch.setattr(race, "_rank", marking)
    again = {
        c.name: len(c.fit.history) > first
        for c in initial.initial_candidates(data, 6, DAMPED_BASIS, **kw)
    }
    assert sum(again[name] for name in marked) == 1  # one in the better half, one out of it
    assert all(again[name] for name in went_on if name not in marked)
    assert sum(again[name] for name in raced if name not in went_on) == 1


# ------------------------------------------------------------------ the easy case
def test_gantry_does_at_least_as_well_as_the_plain_route():
    ds = lpvid.datasets.gantry()
    data, val = ds.identification, ds.validation
    local = lpvid.identify_lti(data, ds.order)
    assert initial.consistency(local).ok
    cands = initial.initial_candidates(
        data, ds.order, ds.basis, ds.fixed, validation=val, local=local
    )
    plain = [c for c in cands if c.name.startswith("smile:")]
    cont = [c for c in cands if c.name.startswith("continuation+")]
    assert len(plain) == len(cont) >= 4
    best_plain = min(c.validation_vnls for c in plain)
    chosen, _ = initial.choose(cands)
    assert chosen.validation_vnls <= 1.02 * best_plain
    assert chosen.vnls < 1.02 * data.n_residuals
    # Continuation changes little when the local models are consistent.
    assert min(c.validation_vnls for c in cont) <= 1.05 * best_plain
    assert min(c.vnls for c in cont) <= 1.001 * min(c.vnls for c in plain)


# ------------------------------------------------------------------ choose
def fake(name, v, val=None, dep=1.0, stable=True, floor=1000):
    m = lpvid.LpvModel(np.zeros((1, 1, 1)), np.ones((1, 1, 1)), np.ones((1, 1, 1)))
    return initial.Candidate(
        name, m, v, floor, val, None if val is None else 500, 0.0, 0, stable, dependence=dep
    )


def test_choose_prefers_validation_then_simplicity():
    cands = [fake("a", 990, 700), fake("b", 1200, 520), fake("c", 1000, 525, dep=0.3)]
    pick, reason = initial.choose(cands)
    assert pick.name == "c"  # within 2 % of the best validation and simpler
    assert "simplest" in reason
    # Dependences within 5 % of the least tie: then the lower validation V_NLS.
    pick, _ = initial.choose([*cands, fake("d", 1000, 522, dep=0.31)])
    assert pick.name == "d"
    pick, _ = initial.choose([*cands, fake("e", 1000, 522, dep=0.33)])
    assert pick.name == "c"
    pick, _ = initial.choose(cands, tolerance=0.0)
    assert pick.name == "b"
    # A model unstable between the points loses even with the best validation.
    pick, reason = initial.choose([*cands, fake("wild", 980, 400, stable=False)])
    assert pick.name == "c" and "stable" in reason


def test_choose_decides_costs_within_the_cost_tie_by_the_candidates_order():
    """Equally simple starts whose costs differ by less than COST_TIE: the first listed wins.

    Starts that reach the same minimum end up to 3e-4 apart in validation
    V_NLS, and a 1e-12 change of the data moves them by as much: the lower
    of two such costs is not a property of the data (issue 34).
    """
    tie = lpvid.fit.judge.COST_TIE
    a, b = fake("a", 1000, 500 * (1 + 0.9 * tie)), fake("b", 1000, 500)
    assert initial.choose([a, b])[0].name == "a"
    assert initial.choose([b, a])[0].name == "b"
    c = fake("c", 1000, 500 * (1 + 1.1 * tie))
    assert initial.choose([c, b])[0].name == "b"
    # Without validation data the same rule decides the identification V_NLS.
    d, e = fake("d", 1000 * (1 + 0.9 * tie)), fake("e", 1000)
    assert initial.choose([d, e])[0].name == "d"


def test_gantry_start_is_the_same_after_a_1e_12_change_of_the_data():
    """The chosen start is a property of the data, not of its last bits.

    With the lower cost deciding among equally simple starts, the draw
    ``default_rng(7)`` moved the choice from ``smile:observability`` to
    ``continuation+smile:observability`` (its validation V_NLS then within
    1e-4 of the other's), and with it the identified model.
    """
    ds = lpvid.datasets.gantry()
    data, val = ds.identification, ds.validation

    def start(d):
        local = lpvid.identify_lti(d, ds.order)
        cands = initial.initial_candidates(
            d, ds.order, ds.basis, ds.fixed, validation=val, local=local
        )
        return initial.choose(cands)[0].name

    want = start(data)
    for seed in (7, 8):
        noise = 1e-12 * np.random.default_rng(seed).standard_normal(data.G.shape)
        moved = lpvid.FrfData(data.p, data.freqs_hz, data.G * (1 + noise), data.sigma, Ts=data.Ts)
        assert start(moved) == want, seed


def test_choose_without_validation_uses_the_noise_floor_and_stability():
    cands = [
        fake("unstable", 900, stable=False),
        fake("rich", 1000),
        fake("simple", 1060, dep=0.2),  # within 2 sqrt(1000) = 63 of the best stable one
        fake("poor", 1070, dep=0.1),  # not within it
    ]
    pick, reason = initial.choose(cands)
    assert pick.name == "simple"
    assert "stable" in reason and "no validation" in reason
    pick, _ = initial.choose(cands[:1])
    assert pick.name == "unstable"
    with pytest.raises(ValueError, match=r"^candidates: needs at least one candidate"):
        initial.choose([])
    with pytest.raises(TypeError, match=r"^candidates\[0\]: expected a Candidate"):
        initial.choose(["x"])


def test_initial_candidates_rejects_bad_input(hard):
    data, _ = hard
    with pytest.raises(ValueError, match=r"^routes: unknown route 'magic'"):
        initial.initial_candidates(data, 6, DAMPED_BASIS, routes=("plain", "magic"))
    with pytest.raises(TypeError, match=r"^basis: expected an lpvid basis"):
        initial.initial_candidates(data, 6, "p")
    with pytest.raises(TypeError, match=r"^validation: expected an FrfData"):
        initial.initial_candidates(data, 6, DAMPED_BASIS, validation=3)
