"""Which routes a run follows beyond its chosen start's, and the blocks route followed ahead.

:func:`open_routes` decides, once the chosen start's route has been
followed, whether the run needs more: without validation data, when the
measured points leave the chosen structure open (the count of
:func:`lpvid.pipeline.routes.count_silent`), the blocks route
(:mod:`lpvid.initial.blocks`); after a misfit (:mod:`lpvid.pipeline.misfit`),
with or without validation data, the blocks route and the global start from
every point; after a far fit, starts grown over the points
(:mod:`lpvid.initial.grown`). The routes it returns compete as
:mod:`lpvid.pipeline.fewpoints` says. A small run hands the blocks route
out before its main path (:class:`FollowAhead` follows its routes in the
pieces that fitted their starts); what is not taken is dropped.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from typing import Any

from lpvid.data.frf import FrfData
from lpvid.fit.judge import noise_slack
from lpvid.initial.blocks import BlockPieces, hand_out_blocks
from lpvid.initial.candidates import Candidate
from lpvid.initial.grown import grown_everywhere
from lpvid.initial.localmodels import LocalModels
from lpvid.pipeline.misfit import far_fit, global_everywhere, misfit
from lpvid.pipeline.path import Along
from lpvid.pipeline.routes import Route, count_silent, follow
from lpvid.trust.silent import SilentCount

__all__ = ["FollowAhead", "Followed", "open_routes"]


def open_routes(
    problem: Any,
    main: Route,
    local: LocalModels,
    follow_start: Callable[[Candidate], Route],
    say: Callable[[str], Any],
    executor: Executor | None = None,
    ahead: BlockPieces | None = None,
) -> tuple[list[Route], list[Candidate], SilentCount | None]:
    """The routes to choose among, the extra candidates, and the count that decided.

    Only ``main`` when it is no misfit (:mod:`lpvid.pipeline.misfit`) and
    the points determine its chosen structure (or the count cannot be
    made) or validation data judge what lies between them.
    When the points leave the structure open: also the blocks route, from
    every start of :func:`lpvid.initial.blocks.start_points`. After a
    misfit: the blocks route from every point and the global start
    (``"global:all"``) from every point. Of the extra starts, those within
    the noise of the committee (module notes) are followed through the path.
    When the chosen model sits far above the local models' level but is no
    misfit (:func:`lpvid.pipeline.misfit.far_fit`): also starts grown over
    the points from every point (:mod:`lpvid.initial.grown`).

    ``ahead``: the blocks route's fits from its usual start points, handed
    out before ``main`` was followed
    (:func:`lpvid.initial.blocks.hand_out_blocks`); taken when the points
    leave the structure open, else dropped. The routes its pieces followed
    already (their ``after``, :class:`FollowAhead`) are taken as they are.
    """
    try:
        data, validation = problem.data, problem.validation
        threshold = problem.settings.path.l21.threshold
        e = main.entry
        wrong = misfit(e.vnls, e.noise_floor, local, e.validation_vnls, e.validation_floor)
        # With validation data they judge what lies between the points: only a misfit opens routes.
        if problem.time_data is not None or (not wrong and validation is not None):
            return [main], [], None
        count = None if wrong else count_silent(e.model, data, main.fixed, threshold)[0]
        main.counted = count
        far = None if wrong else far_fit(e.vnls, e.noise_floor, local)
        grow = far is not None and data.n_points > len(problem.basis) + 1
        opens = wrong or (count is not None and not count.determined)
        if not opens and not grow:
            return [main], [], count
        starts = problem.settings.starts
        points: Sequence[int] | None = None
        if wrong:
            say(f"misfit: {wrong}; the blocks route and global starts from every point")
            points = range(data.n_points)
        elif opens:
            assert count is not None
            opened = f"the points leave the chosen structure open: {count.describe()}"
            say(f"{opened}; the blocks route too")
        if grow:
            say(f"{far}; starts grown over the points from every point")
        if ahead is not None and (points is not None or not opens):
            ahead.drop()  # handed out from the usual start points; a misfit starts from every point
            ahead = None
        if ahead is None and opens:
            ahead = hand_out_blocks(
                data,
                problem.basis,
                problem.fixed,
                local,
                validation=validation,
                points=points,
                max_iter=starts.max_iter,
                ftol=starts.ftol,
                executor=executor,
            )
        more = [] if ahead is None else ahead.take()
        followed = {} if ahead is None else ahead.after  # routes followed ahead, by start name
        if wrong:
            more += global_everywhere(problem, local, executor)
        if grow:
            how = (problem.order, problem.basis, problem.fixed, local)
            more += grown_everywhere(
                data, *how, max_iter=starts.max_iter, ftol=starts.ftol, executor=executor
            )
        floor = data.n_residuals
        best = min([e.vnls for e in main.entries] + [c.vnls for c in more])
        limit = max(best, floor) + noise_slack(floor)
        routes = [main]
        for c in more:
            say(f"  {c.name}: V_NLS {c.vnls:.5g}" + ("" if c.stable else ", unstable"))
            if c.vnls <= limit or (wrong and c.vnls < e.vnls):
                ready = followed.get(c.name)
                if ready is None:
                    routes.append(follow_start(c))
                    continue
                for message in ready.said:
                    say(message)
                routes.append(ready.route)
        return routes, more, count
    finally:
        if ahead is not None:
            ahead.drop()  # nothing left when taken


@dataclass
class Followed:
    """A route followed ahead (:class:`FollowAhead`) and what it said on the way."""

    route: Route
    said: list[str]


@dataclass(frozen=True)
class FollowAhead:
    """The blocks route's paths, followed in the piece that fitted their starts.

    The ``after`` of :func:`lpvid.initial.blocks.hand_out_blocks` in a run
    that hands the blocks route out before its main path: every candidate
    of the piece that :func:`open_routes` could follow (its V_NLS within
    the noise of the least of the piece's candidates and the floor: the
    limit there is at most that, its least V_NLS also counting the main
    path's entries and the other pieces') is followed through the path,
    and its chosen entry counted (:func:`simplest_choices` asks for it).
    ``along`` is the main path's, but for its ``say`` (the messages are
    kept and said when the route is taken) and its executor (none: the
    piece is where the route's fits run). What is not taken is dropped;
    what is taken is the route :func:`open_routes` would have followed
    itself, to the last bit.
    """

    data: FrfData
    gammas: tuple[float, ...]
    along: Along
    threshold: float

    def __call__(self, found: list[Candidate]) -> dict[str, Followed]:
        """The routes of the candidates within the limit, by their name."""
        floor = self.data.n_residuals
        limit = max(min(c.vnls for c in found), floor) + noise_slack(floor)
        out = {}
        for c in found:
            if c.vnls <= limit:
                said: list[str] = []
                along = replace(self.along, say=said.append, executor=None)
                route = follow(c.name, c.fit, self.gammas, self.data, c.structure, along)
                route.counted = count_silent(
                    route.entry.model, self.data, route.fixed, self.threshold
                )[0]
                out[c.name] = Followed(route, said)
        return out
