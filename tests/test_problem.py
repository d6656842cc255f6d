"""lpvid.Problem: an identification problem checked once, and identify on it."""

from __future__ import annotations

import numpy as np
import pytest

import lpvid
import lpvid.testing
from lpvid.fit.judge import identify_range
from lpvid.fit.settings import DEFAULT_GAMMAS, FORMS, ROUTES, START_FTOL


@pytest.fixture(scope="module")
def small():
    rng = np.random.default_rng(0)
    true = lpvid.testing.modal_lpv([[10.0, 3.0]])  # order 2, linear in p
    f = np.linspace(2, 30, 40)
    data = lpvid.testing.noisy_data(true, [0.0, 0.5, 1.0], f, rng, 0.01)
    val = lpvid.testing.noisy_data(true, [0.25, 0.75], f, rng, 0.01)
    return data, val, lpvid.Polynomial(1, domain=(0.0, 1.0))


def test_identify_on_a_problem_is_identify_on_its_arguments(small):
    data, val, basis = small
    kw = dict(gammas=[0.1, 0.01], validation=val, fixed={"D": True}, tolerance=0.05)
    direct = lpvid.identify(data, 2, basis, **kw)
    settings = lpvid.IdentifySettings(path=lpvid.PathSettings(gammas=(0.1, 0.01), tolerance=0.05))
    problem = lpvid.Problem(data, 2, basis, validation=val, fixed={"D": True}, settings=settings)
    via = lpvid.identify(problem)
    assert via.model.theta.tobytes() == direct.model.theta.tobytes()
    assert [e.model.theta.tobytes() for e in via.entries] == [
        e.model.theta.tobytes() for e in direct.entries
    ]
    assert (via.chosen, via.reason, via.start) == (direct.chosen, direct.reason, direct.start)
    # the range the problem holds is the one identify judged on before it held one
    assert problem.p_range == identify_range(direct.initial, data)


def test_identify_checks_the_data_once(small, monkeypatch):
    data, val, basis = small
    made = {"FrfData": 0, "Problem": 0}
    frf_init, problem_init = lpvid.FrfData.__init__, lpvid.Problem.__post_init__

    def counted_frf(self, *args, **kwargs):
        made["FrfData"] += 1
        frf_init(self, *args, **kwargs)

    def counted_problem(self):
        made["Problem"] += 1
        problem_init(self)

    monkeypatch.setattr(lpvid.FrfData, "__init__", counted_frf)
    monkeypatch.setattr(lpvid.Problem, "__post_init__", counted_problem)
    lpvid.identify(data, 2, basis, gammas=[0.1], validation=val)
    # one check of everything; no stage rebuilds (and re-checks) the data,
    # the local models' subsets of one point included
    assert made == {"FrfData": 0, "Problem": 1}
    problem = lpvid.Problem(data, 2, basis, validation=val)
    made.update(FrfData=0, Problem=0)
    lpvid.identify(problem)
    assert made == {"FrfData": 0, "Problem": 0}


def _message(exc_type, call):
    with pytest.raises(exc_type) as info:
        call()
    return str(info.value)


@pytest.mark.parametrize(
    "args, kw, problem_kw, exc_type",
    [
        ((2, "poly"), {}, {}, TypeError),
        ((0, None), {}, {}, ValueError),
        ((2, lpvid.Polynomial(3, domain=(0, 1))), {}, {}, ValueError),
        ((99, None), {}, {}, ValueError),
        ((2, None), {"validation": "val"}, {"validation": "val"}, TypeError),
        ((2, None), {"fixed": {"Q": True}}, {"fixed": {"Q": True}}, ValueError),
        ((2, None), {"time_data": 3.0}, {"time_data": 3.0}, TypeError),
    ],
)
def test_bad_input_is_refused_at_creation_with_identifys_message(
    small, args, kw, problem_kw, exc_type
):
    data, _, basis = small
    order, b = args[0], basis if args[1] is None else args[1]
    today = _message(exc_type, lambda: lpvid.identify(data, order, b, **kw))
    assert _message(exc_type, lambda: lpvid.Problem(data, order, b, **problem_kw)) == today
    assert today.split(":")[0] in {"basis", "order", "validation", "fixed", "time_data"}


def test_a_progress_that_is_no_callable_is_refused_before_any_work(small, monkeypatch):
    """``progress=True`` (as a verbose flag) once failed at the first message, deep inside."""
    from lpvid.pipeline import run

    data, _, basis = small
    started = []
    monkeypatch.setattr(run, "local_models", lambda *a, **k: started.append(1))
    for bad in (True, "log", 1):
        with pytest.raises(TypeError, match=r"^progress: expected a callable taking one str"):
            lpvid.identify(data, 2, basis, progress=bad)
    assert not started
    said = []
    with pytest.raises((TypeError, AttributeError)):  # the patched stage returned None
        lpvid.identify(data, 2, basis, progress=said.append)
    assert started and said[0] == "local models: order 2 at 3 scheduling points"


def test_bad_settings_refused_with_identifys_message(small):
    data, _, basis = small
    cases = [
        (dict(gammas=[0.1, -1]), lambda: lpvid.PathSettings(gammas=(0.1, -1))),
        (dict(tolerance=-1.0), lambda: lpvid.PathSettings(tolerance=-1.0)),
        (dict(routes=("plain", "nope")), lambda: lpvid.StartSettings(routes=("plain", "nope"))),
        (dict(forms=["nope"]), lambda: lpvid.StartSettings(forms=["nope"])),
        (dict(settings="fast"), lambda: lpvid.PathSettings(l21="fast")),
    ]
    for kw, make in cases:
        with pytest.raises((ValueError, TypeError)) as today:
            lpvid.identify(data, 2, basis, **kw)
        with pytest.raises(type(today.value)) as now:
            make()
        assert str(now.value) == str(today.value)


def test_no_argument_beside_a_problem(small):
    data, _, basis = small
    problem = lpvid.Problem(data, 2, basis)
    with pytest.raises(TypeError, match=r"^gammas, stable: the problem holds these"):
        lpvid.identify(problem, gammas=[0.1], stable=True)


def test_identify_and_select_take_their_held_arguments_from_the_one_record():
    """identify's signature gives every argument of the record, with the record's default."""
    import dataclasses
    import inspect

    from lpvid.pipeline.problem import IdentifyArguments

    record = {f.name: f.default for f in dataclasses.fields(IdentifyArguments)}
    params = inspect.signature(lpvid.identify).parameters
    assert {name: params[name].default for name in record} == record
    shared = inspect.signature(lpvid.select).parameters
    for name in ("validation", "gammas", "fixed", "tolerance"):
        assert shared[name].default == record[name], name
    # every argument of identify is in the record or is one it takes beside the problem
    assert set(params) - set(record) == {"data", "progress", "executor"}
    given = IdentifyArguments(tolerance=0.1, stable=True, routes=list(IdentifyArguments.routes))
    assert given.given() == ["routes", "stable"]  # a list is not the default tuple


def test_the_record_makes_the_problem_with_every_argument(small):
    """Each argument reaches the problem's settings; left out, each has identify's default."""
    from lpvid.fit.settings import DEFAULT_GAMMAS
    from lpvid.pipeline.problem import IdentifyArguments

    data, _, basis = small
    given = IdentifyArguments(
        order=2,
        basis=basis,
        gammas=[0.1, 0.01],
        routes=("plain",),
        forms=("modal",),
        tolerance=0.3,
        settings=lpvid.L21Settings(max_outer=3),
        stable=True,
        refit=False,
    )
    s = given.problem(data).settings
    assert s.path.gammas == (0.1, 0.01) and s.path.tolerance == 0.3
    assert s.path.l21 == lpvid.L21Settings(max_outer=3)
    assert s.starts.routes == ("plain",) and s.starts.forms == ("modal",)
    assert s.stable is True and s.refit is False
    d = IdentifyArguments(order=2, basis=basis).problem(data).settings
    assert d.path.l21 == lpvid.L21Settings(max_outer=10)
    assert d.path.gammas == tuple(DEFAULT_GAMMAS) and d.path.tolerance == 0.1
    assert d.starts == lpvid.StartSettings() and d.stable is False and d.refit is True
    with pytest.raises(
        TypeError,
        match=r"^refit: the problem holds these; give them to "
        r"lpvid.Problem \(or problem.replace\(...\)\), not beside it$",
    ):
        IdentifyArguments(refit=False).refuse()


def test_defaults_in_one_place_and_visible(small):
    data, _, basis = small
    s = lpvid.Problem(data, 2, basis).settings
    assert s.path.l21 == lpvid.L21Settings(max_outer=10)
    assert s.path.gammas == DEFAULT_GAMMAS and s.path.tolerance == 0.1
    assert (s.starts.routes, s.starts.forms, s.starts.max_iter) == (ROUTES, FORMS, 100)
    assert s.starts.ftol == START_FTOL and s.starts.halving
    assert (s.stable, s.refit) == (False, True)
    assert lpvid.LmSettings().to_core() == dict(
        max_iter=100, xtol=1e-10, ftol=1e-10, gtol=0.0, lambda0=1e-2
    )
    with pytest.raises(TypeError, match=r"^stable: expected True or False"):
        lpvid.IdentifySettings(stable="yes")
    with pytest.raises(TypeError, match=r"^gamma: not a setting of the path"):
        lpvid.PathSettings().replace(gamma=0.1)
    with pytest.raises(TypeError, match=r"^max_iter: expected an integer"):
        lpvid.LmSettings(max_iter=1.5)


def test_replace_checks_again_and_derives_the_range_anew(small):
    data, _, basis = small
    problem = lpvid.Problem(data, 2, basis)
    wider = problem.replace(p_range=(-1.0, 2.0))
    assert wider.p_range == [-1.0, 2.0] and problem.p_range == [0.0, 1.0]
    assert wider.replace(data=data.subset([0, 1, 2])).p_range == [0.0, 1.0]
    with pytest.raises(ValueError, match=r"^order: expected an integer >= 1"):
        problem.replace(order=0)
    with pytest.raises(TypeError, match=r"^n: not a field of Problem"):
        problem.replace(n=3)
    assert problem.mask.shape == problem.replace(fixed={"D": True}).mask.shape


def test_subset_takes_checked_points_as_they_are(small):
    data, _, _ = small
    part = data.subset([2, 0])
    rebuilt = lpvid.FrfData(data.p[[2, 0]], data.freqs_hz, data.G[[2, 0]], data.sigma[[2, 0]])
    for name in ("p", "freqs_hz", "G", "sigma"):
        assert getattr(part, name).tobytes() == getattr(rebuilt, name).tobytes()
        assert not getattr(part, name).flags.writeable
    assert part.Ts == data.Ts and part.provenance is None
    with pytest.raises(ValueError, match=r"^p: scheduling values must be distinct"):
        data.subset([0, 0])
    with pytest.raises(ValueError, match=r"^p: needs at least one scheduling point"):
        data.subset([])


def test_select_on_a_problem_is_select_on_its_arguments(small):
    data, val, basis = small
    direct = lpvid.select(data, [2], [1], validation=val, gammas=[0.1])
    settings = lpvid.IdentifySettings(path=lpvid.PathSettings(gammas=(0.1,)))
    problem = lpvid.Problem(data, 2, basis, validation=val, settings=settings)
    via = lpvid.select(problem, [2], [1])
    assert via.model.theta.tobytes() == direct.model.theta.tobytes()
    with pytest.raises(TypeError, match=r"^gammas: the problem holds these"):
        lpvid.select(problem, [2], [1], gammas=[0.1])


# ---------------------------------------------- the functions below the pipeline


@pytest.fixture(scope="module")
def started(small):
    """A problem with a fixed D and one-step l2,1 fits, and a start model for it."""
    data, _, basis = small
    start = lpvid.smile(lpvid.identify_lti(data, 2), basis=basis, form="observability")
    l21 = lpvid.L21Settings(max_outer=1)
    settings = lpvid.IdentifySettings(path=lpvid.PathSettings(l21=l21))
    problem = lpvid.Problem(data, 2, basis, fixed={"D": True}, settings=settings)
    return problem, start


def test_the_fits_take_a_problem_for_its_data_mask_range_and_l21_settings(started):
    """Rejects a Problem taken for plain data, or its mask, range or l2,1 settings dropped."""
    problem, start = started
    data, fixed, rng = problem.data, problem.fixed, problem.p_range
    l21 = problem.settings.path.l21
    a = lpvid.fit_nls(start, problem, max_iter=4, warn=False)
    b = lpvid.fit_nls(start, data, fixed, p_range=rng, max_iter=4, warn=False)
    assert np.array_equal(a.model.theta, b.model.theta)
    assert np.array_equal(a.model.D, start.D)  # the problem's fixed D held
    a = lpvid.fit_l21(start, problem, 1e-2, warn=False)
    b = lpvid.fit_l21(start, data, 1e-2, l21, fixed, p_range=rng, warn=False)
    assert np.array_equal(a.model.theta, b.model.theta)
    assert a.outer_iterations == b.outer_iterations == 1  # max_outer=1 from the problem
    a = lpvid.l21_path(start, problem, [1e-1, 1e-2], warn=False)
    b = lpvid.l21_path(start, data, [1e-1, 1e-2], l21, fixed, p_range=rng, warn=False)
    assert [np.array_equal(x.model.theta, y.model.theta) for x, y in zip(a, b, strict=True)] == [
        True,
        True,
    ]


def test_refit_covariance_and_stability_take_a_problem(started):
    """Rejects a Problem's mask or range ignored by the refit, covariance or stability check."""
    problem, start = started
    data, fixed, rng = problem.data, problem.fixed, problem.p_range
    fit, held = lpvid.refit(start, problem, max_iter=3, warn=False)
    fit2, held2 = lpvid.refit(start, data, fixed, p_range=rng, max_iter=3, warn=False)
    assert np.array_equal(fit.model.theta, fit2.model.theta)
    assert np.array_equal(held, held2)
    assert held[lpvid.fixed_mask(start, {"D": True})].all()  # the problem's fixed D held
    cov = lpvid.covariance(fit.model, problem, warn=False)
    cov2 = lpvid.covariance(fit.model, data, fixed, warn=False)
    assert np.array_equal(cov.theta, cov2.theta) and np.array_equal(cov.free, cov2.free)
    assert cov.n_free < start.theta.size  # D fixed: not all free
    inner = problem.replace(p_range=[0.2, 0.8])
    report = lpvid.stability(start, inner, quadratic=False)
    assert report.p_range == lpvid.stability(start, [0.2, 0.8], quadratic=False).p_range
    assert report.p_range != lpvid.stability(start, quadratic=False).p_range


@pytest.mark.parametrize(
    ("call", "names"),
    [
        (lambda p, m: lpvid.fit_nls(m, p, {"D": True}), "fixed"),
        (lambda p, m: lpvid.fit_l21(m, p, 0.1, p_range=[0, 1]), "p_range"),
        (
            lambda p, m: lpvid.l21_path(m, p, [0.1], fixed={"B": True}, p_range=[0, 1]),
            "fixed, p_range",
        ),
        (lambda p, m: lpvid.refit(m, p, p_range=[0, 1]), "p_range"),
        (lambda p, m: lpvid.covariance(m, p, {"D": True}), "fixed"),
    ],
)
def test_what_a_problem_holds_is_not_given_beside_it(started, call, names):
    """Rejects an argument silently overriding (or overridden by) the Problem's own."""
    problem, start = started
    them = "it" if "," not in names else "them"
    with pytest.raises(
        TypeError, match=rf"^{names}: held by the Problem given as data; set {them} there"
    ):
        call(problem, start)
