"""When the measured points leave the chosen structure open: a committee of fits and its consensus.

With few measured points the data leave a family of models that fit every
point within the noise and differ between them (:mod:`lpvid.trust.silent`
counts the directions they leave open). Without validation data to judge
them, :func:`lpvid.identify` then follows more routes than the chosen
start's: the blocks route (:mod:`lpvid.initial.blocks`: modal form held,
which removes the couplings between modes that no point sees), from the
best-determined point and from the ends of the range. After a misfit
(:mod:`lpvid.pipeline.misfit`), with or without validation data, it
follows the blocks route and the global start from every point. Every
entry of every path that fits the data within the noise is a member of
the *committee*:

    V_NLS <= max(best V_NLS, M) + 2 sqrt(M)

(``M`` complex residuals, :func:`lpvid.fit.judge.noise_slack`; the floor
``M`` enters so that a family of over-fitted models, all below the floor,
does not shut out one that fits as the truth would). Misfits
(:mod:`lpvid.pipeline.misfit`) are no members, nor, without validation
data, fits that bulge (:mod:`lpvid.pipeline.bulge`) unless every one does.

**The rule.** Without validation data, the model returned is the
committee's consensus, once the blocks route agrees with itself
(:func:`consistent`: its starts' choices closer to each other than the
chosen start's choice is to the nearest of them; else that choice stands).
The routes' own choices (each path's entry by its
knee, :func:`lpvid.pipeline.routes.path_choice`) that are members are
scored ``V_NLS + 2 K``, ``K`` the directions their structure has over the
range (:func:`simplest_choices`, :data:`COMPLEXITY`: a direction the
points cannot hold is paid for like a fitted parameter, at twice Akaike's
price); those within the noise (``2 sqrt(M)``) of the least score compete,
and of them the one whose frozen FRF over the range is nearest the
members' is returned (the least
median, over the other members, of the largest relative distance over a
grid of the range, :func:`distances`), among the members whose frozen
models are stable between the points when there are any (every member
competes when no route's choice is one). Medians within
:data:`CONSENSUS_TIE` of the least tie, and the first in the routes' order
wins (the chosen start's route first, then the blocks routes). With
validation data (routes opened by a misfit) the judge is the validation
data, as on one path: the simplest entry (fewest groups) whose validation
V_NLS is within ``tolerance`` of the best of every route, those stable
between the points first.

Where the committee disagrees between the points is where the data are
silent: :class:`lpvid.pipeline.between.Between` turns that into a spread,
and :func:`lpvid.next_points` measures there.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid.data.frf import FrfData
from lpvid.data.schedule import between_points
from lpvid.fit.judge import noise_slack
from lpvid.initial.localmodels import LocalModels
from lpvid.model.frozen import frozen_stable
from lpvid.model.lpv import LpvModel
from lpvid.pipeline.between import Between, Member
from lpvid.pipeline.bulge import bulge
from lpvid.pipeline.misfit import misfit
from lpvid.pipeline.routes import Route, count_silent, uncounted
from lpvid.stable.scan import stability
from lpvid.trust.silent import range_grid

__all__ = [
    "COMPLEXITY",
    "CONSENSUS_TIE",
    "choose_route",
    "committee",
    "consistent",
    "consensus",
    "distances",
    "open_between",
    "validated",
]

#: Median distances within this share of the least count as equal (the
#: first member in the routes' order wins).
CONSENSUS_TIE = 0.01

#: What a direction of a route's structure over the range costs in the score
#: that decides which routes' choices compete (twice Akaike's penalty in
#: V_NLS's units, where a fitted real parameter lowers V_NLS by 1/2).
COMPLEXITY = 2.0


def committee(routes: Sequence[Route], data: FrfData) -> list[Member]:
    """Every entry of every route that fits the data within the noise (module notes)."""
    floor = data.n_residuals
    best = min(e.vnls for r in routes for e in r.entries)
    limit = max(best, floor) + noise_slack(floor)
    between = between_points(data.p)
    out = []
    for i, r in enumerate(routes):
        for k, e in enumerate(r.entries):
            if e.vnls <= limit:
                name = f"{r.name}, gamma {e.gamma:g}"
                stable = frozen_stable(e.model, between)
                out.append(Member(i, k, name, e.model, float(e.vnls), stable))
    return out


def distances(models: Sequence[LpvModel], data: FrfData) -> NDArray[np.float64]:
    """The largest relative distance between the frozen FRFs of every two models over the range.

    On the data's lines and a grid over the range (:func:`lpvid.trust.silent.range_grid`):
    ``max_p ||G_a(p) - G_b(p)|| / s(p)``, Frobenius norms over every line,
    output and input, ``s(p)`` the mean of the models' norms at ``p``.
    """
    grid = range_grid(models[0], data)
    G = np.array([m.frf(data.freqs_hz, grid).reshape(len(grid), -1) for m in models])
    scale = np.mean(np.linalg.norm(G, axis=2), axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    # Each pair once (all at once, a (K, K, grid, lines) array, took 3-15 times
    # as long for 2-30 models); ||G_b - G_a|| is ||G_a - G_b|| to the last bit.
    out = np.zeros((len(models), len(models)))
    for a in range(len(models) - 1):
        d = (np.linalg.norm(G[a + 1 :] - G[a], axis=2) / scale).max(axis=1)
        out[a, a + 1 :] = d
        out[a + 1 :, a] = d
    return out


def consensus(
    members: Sequence[Member], data: FrfData, choices: Sequence[tuple[int, int]] = ()
) -> tuple[Member, str]:
    """The committee's consensus (module notes), and why.

    ``choices`` are the ``(route, index)`` of the routes' choices that
    compete (each path's choice of simplicity stands), scored against every
    member; all members compete when none of them is one. Of the
    competitors, those whose frozen models are stable over the whole range
    (:func:`lpvid.stability`'s exact test) come first.
    """
    if len(members) == 1:
        return members[0], "the only fit within the noise"
    pool = [m for m in members if m.stable] or list(members)
    if len(pool) == 1:
        return pool[0], "the only fit within the noise stable between the points"
    chosen = set(choices)
    compete = [k for k, m in enumerate(pool) if (m.route, m.index) in chosen] or list(
        range(len(pool))
    )
    steady = [k for k in compete if stability(pool[k].model, quadratic=False).stable]
    compete = steady or compete
    D = distances([m.model for m in pool], data)
    med = np.array([np.median(np.delete(D[k], k)) for k in compete])
    least = float(med.min())
    j = int(np.flatnonzero(med <= least * (1 + CONSENSUS_TIE))[0])
    which = "stable " if len(pool) < len(members) else ""
    return pool[compete[j]], (
        f"of the routes' choices, the one nearest the {len(pool)} {which}fits within the noise "
        f"of every route between the points (median distance {med[j]:.3g}): their consensus"
    )


def validated(routes: Sequence[Route], tolerance: float, data: FrfData) -> tuple[int, int, str]:
    """With validation data: the simplest entry of every route within ``tolerance`` of the best.

    Entries whose frozen models are stable between the points come first
    when any is within ``tolerance``.
    """
    entries = [(i, k, e) for i, r in enumerate(routes) for k, e in enumerate(r.entries)]
    vals = np.array([float(e.validation_vnls) for _, _, e in entries])  # type: ignore[arg-type]
    best = float(vals.min())
    ok = [j for j in range(len(entries)) if vals[j] <= (1 + tolerance) * best]
    between = between_points(data.p)
    stable = [j for j in ok if frozen_stable(entries[j][2].model, between)]
    j = min(stable or ok, key=lambda j: (entries[j][2].n_groups, vals[j], j))
    i, k, _ = entries[j]
    which = "stable " if stable else ""
    return (
        i,
        k,
        (
            f"the simplest {which}model of every route whose validation V_NLS ({vals[j]:.5g}) is "
            f"within {tolerance:.0%} of the best ({best:.5g})"
        ),
    )


def choose_route(
    routes: Sequence[Route],
    data: FrfData,
    validation: FrfData | None,
    tolerance: float,
    local: LocalModels,
    threshold: float = 1e-6,
) -> tuple[int, int, str, list[Member]]:
    """The route and entry returned, why, and the other members of the committee.

    The members returned are those of the routes whose choices competed
    (:func:`simplest_choices`): the spread between the points and the plan
    of the next measurement follow the routes the data left in the running.

    ``threshold``: the relative group magnitude at or below which a group
    counts as dropped (the structures' counts, made here where a route
    does not hold its own, :attr:`~lpvid.pipeline.routes.Route.counted`).

    Members that are misfits (:func:`lpvid.pipeline.misfit.misfit`) leave the
    committee; when none is left, the routes' own choices compete on V_NLS.
    Without validation data, members that bulge (:mod:`lpvid.pipeline.bulge`)
    leave it too, unless every one does.
    """
    main = routes[0]
    if len(routes) == 1:
        return 0, main.chosen, main.reason, []
    members = [m for m in committee(routes, data) if not misfit(m.vnls, data.n_residuals, local)]
    if validation is None:
        calm = [m for m in members if not bulge(m.model, data).bulges]
        members = calm or members
    if validation is not None:
        i, k, reason = validated(routes, tolerance, data)
    elif not members:
        i = min(range(len(routes)), key=lambda j: (routes[j].entry.vnls, j))
        k = routes[i].chosen
        reason = f"{routes[i].reason}; no route fits within the noise: the lowest V_NLS of them"
    elif not consistent(routes, members, data):
        i, k = 0, main.chosen
        reason = (
            f"{main.reason}; the blocks route's starts land on models further apart than "
            "the chosen start's model is from the nearest of them: that form does not hold "
            "for these data, and the chosen start's model stands"
        )
        members = [m for m in members if m.route == 0]
    else:
        choices, why = simplest_choices(routes, members, data, threshold)
        pick, reason = consensus(members, data, choices)
        reason = f"{reason}; {why}"
        i, k = pick.route, pick.index
        # the spread and the plan follow the routes that competed
        plausible = {r for r, _ in choices} or {i}
        members = [m for m in members if m.route in plausible]
    others = [m for m in members if (m.route, m.index) != (i, k)]
    return i, k, reason, others


def consistent(routes: Sequence[Route], members: Sequence[Member], data: FrfData) -> bool:
    """Whether the other routes agree with themselves more than with the chosen start's route.

    The largest distance (:func:`distances`) between the choices of the
    routes after the first that are members must be below the distance from
    the first route's choice to the nearest of them. A form the data
    support gives the same model from every start; one that lands on models
    further apart than the first route's is fighting the data. True when
    the first route's choice is no member, or fewer than two others are.
    """
    inside = {(m.route, m.index) for m in members}
    if (0, routes[0].chosen) not in inside:
        return True
    others = [r.entry.model for i, r in enumerate(routes) if i and (i, r.chosen) in inside]
    if len(others) < 2:
        return True
    D = distances([routes[0].entry.model, *others], data)
    return float(D[1:, 1:].max()) < float(D[0, 1:].min())


def simplest_choices(
    routes: Sequence[Route],
    members: Sequence[Member],
    data: FrfData,
    threshold: float,
) -> tuple[list[tuple[int, int]], str]:
    """The routes' choices that compete in the consensus (module notes), and why.

    Each route's choice that is a member is scored ``V_NLS + COMPLEXITY K``,
    ``K`` the directions its structure has over the range
    (``SilentCount.over_range`` of :mod:`lpvid.trust.silent`: those the points see
    and those they leave open); those within the noise (``2 sqrt(M)``) of
    the least score compete. A route's count is its own when already made
    (:attr:`~lpvid.pipeline.routes.Route.counted`, at ``threshold``).
    """
    inside = {(m.route, m.index) for m in members}
    scored = []
    for i, r in enumerate(routes):
        if (i, r.chosen) not in inside:
            continue
        count = r.counted
        if count is None:
            count, _ = count_silent(r.entry.model, data, r.fixed, threshold)
        k = 0 if count is None else count.over_range
        scored.append(((i, r.chosen), r.entry.vnls + COMPLEXITY * k, k))
    if not scored:
        return [], "no route's own choice fits within the noise"
    least = min(s for _, s, _ in scored)
    slack = noise_slack(data.n_residuals)
    keep = [c for c, s, _ in scored if s <= least + slack]
    return keep, (
        f"{len(keep)} of the routes' {len(scored)} choices within the noise of the least "
        f"V_NLS + {COMPLEXITY:g} x directions over the range"
    )


def open_between(
    done: Any,
    members: list[Member],
    data: FrfData,
    threshold: float,
    time_cost: Any,
) -> Between:
    """The :class:`~lpvid.pipeline.between.Between` of the model returned.

    Counted when first asked for; not with time records, or a structure of
    more than :data:`lpvid.pipeline.routes.MAX_COUNTED` free parameters (the note says why).
    """
    note = uncounted(int((~done.fixed).sum()), time_cost)
    return Between(
        model=done.model,
        members=members,
        covariance=done.covariance,
        data=data,
        held=done.fixed,
        threshold=threshold,
        note=note,
    )
