"""Evaluate tuning policies on the same flights: :func:`evaluate`, the job of ``aeromag evaluate``.

Checks the request, flies every policy on the same test seeds of each scenario (here or on Ray:
:func:`agents.evaluation.episodes.evaluate_scenarios`) and writes per scenario ``results.json``,
``evaluation.png`` and ``report.html`` as a set. :func:`evaluation_table` is a scenario's
results as the Markdown table the command line prints and ``aeromag demo`` writes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env import reports
from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.environment.scenarios import check_scenario
from aeromag_env.errors import ArgumentError
from aeromag_env.jobs.limits import MAX_EPISODES, SEED_RANGE, check_count
from aeromag_env.jobs.reports import jsonable
from aeromag_env.parallel import retry_note, runner
from agents.evaluation.episodes import action_traces, evaluate_scenarios
from agents.evaluation.seeds import TEST_SEED_START
from agents.policies import POLICIES
from agents.training.quick import QUICK

#: The output set of an evaluation, per scenario.
OUTPUTS = ("results.json", "evaluation.png", reports.PAGE)
#: Flights per scenario, at most, in the reduced mode (``AEROMAG_QUICK=1``,
#: :mod:`aeromag_env.quick`): the experiments' quick evaluations'.
QUICK_EPISODES = QUICK.episodes


@dataclass(frozen=True, kw_only=True)
class EvaluateRequest:
    """What an evaluation is asked for (validated by :meth:`check`).

    Attributes
    ----------
    scenarios : tuple of str
        Distinct scenarios of :data:`~aeromag_env.environment.scenarios.SCENARIOS`.
    policies : tuple of str
        Names of :data:`agents.policies.POLICIES`, or ``ppo:PATH`` for an exported policy file.
    episodes : int
        Flights (seeds) per scenario, in [1, :data:`~aeromag_env.jobs.limits.MAX_EPISODES`].
    seed_start : int
        The first test seed (the flights are ``seed_start … seed_start + episodes − 1``), at
        least :data:`~agents.evaluation.seeds.TEST_SEED_START`.
    out : Path or None
        The output folder: one scenario's set in ``out``, several in ``out/<scenario>/`` (None:
        nothing written).
    ray : str or None
        None: this process; ``local`` or an address: on Ray (:func:`aeromag_env.parallel.runner`).
    html : bool
        Write ``report.html`` too (with the first flight's Q/R scales under each policy).
    """

    scenarios: tuple[str, ...]
    policies: tuple[str, ...]
    episodes: int = 20
    seed_start: int = TEST_SEED_START
    out: Path | None = None
    ray: str | None = None
    html: bool = True

    def check(self) -> None:
        """One-line errors for unusable arguments, before any flight is flown."""
        names = self.scenarios
        if not names or len(set(names)) < len(names):
            raise ArgumentError(
                "scenarios", "takes one or more distinct scenarios", ",".join(names)
            )
        for s in names:
            check_scenario(s)
        unknown = [p for p in self.policies if p not in POLICIES and not p.startswith("ppo:")]
        if unknown or not self.policies:
            raise ArgumentError(
                "policies",
                f"takes names of {', '.join(POLICIES)} or ppo:PATH",
                unknown[0] if unknown else "",
            )
        check_count(
            "episodes",
            self.episodes,
            1,
            MAX_EPISODES,
            "flights",
            "the 95 % intervals narrow as 1/√n; more only costs time",
        )
        hi = SEED_RANGE[1] - self.episodes + 1
        check_count(
            "seed_start",
            self.seed_start,
            TEST_SEED_START,
            hi,
            f"with {self.episodes} episodes",
            f"training and validation use the seeds below {TEST_SEED_START}; seeds end at 2³² − 1",
        )

    def outputs(self) -> tuple[str, ...]:
        """Each scenario's output set: :data:`OUTPUTS`, without the page when ``html`` is off."""
        return OUTPUTS if self.html else tuple(n for n in OUTPUTS if n != reports.PAGE)

    def folders(self) -> dict[str, Path]:
        """Scenario → its output folder (none without ``out``)."""
        if self.out is None:
            return {}
        return {s: self.out if len(self.scenarios) == 1 else self.out / s for s in self.scenarios}

    def policy_files(self) -> list[Path]:
        """The exported policy files the run reads (never overwritten)."""
        return [Path(p[4:]) for p in self.policies if p.startswith("ppo:")]


@dataclass(frozen=True)
class EvaluationResult:
    """What :func:`evaluate` produced.

    Attributes
    ----------
    results : dict
        Scenario → its ``results.json`` content (each policy's RMSE [nT] with its interval,
        paired differences against ``fis``, the normalized score).
    paths : tuple of Path
        The files written (empty without ``out``).
    note : str or None
        What the runner has to say about retried tasks (Ray), or None.
    """

    results: dict[str, dict[str, Any]]
    paths: tuple[Path, ...]
    note: str | None

    def tables(self) -> dict[str, str]:
        """Scenario → its results as Markdown (:func:`evaluation_table`)."""
        return {name: evaluation_table(r) for name, r in self.results.items()}


def scenario_names(scenarios: str | Sequence[str]) -> tuple[str, ...]:
    """``scenarios`` as a tuple: one name, several comma-separated, or a sequence."""
    text = scenarios if isinstance(scenarios, str) else ",".join(scenarios)
    return tuple(s.strip() for s in text.split(",") if s.strip())


def evaluate(
    scenarios: str | Sequence[str],
    policies: Sequence[str],
    *,
    episodes: int = 20,
    seed_start: int = TEST_SEED_START,
    out: str | Path | None = None,
    ray: str | None = None,
    html: bool = True,
    progress: Callable[[int], Any] | None = None,
) -> EvaluationResult:
    """Every policy on the same flights of each scenario, as ``aeromag evaluate`` runs them.

    Parameters
    ----------
    scenarios : str or sequence of str
        One scenario, several comma-separated, or a sequence of distinct scenarios.
    policies : sequence of str
        Names of :data:`agents.policies.POLICIES`, or ``ppo:PATH`` for an exported policy file.
    episodes, seed_start, out, ray, html
        See :class:`EvaluateRequest`.
    progress : callable or None
        Called with 1 after each episode.

    Returns
    -------
    EvaluationResult

    Raises
    ------
    AeromagError
        An unknown scenario or policy, no policy, an episode count or first seed outside its
        range, or an output that is an input (one line), before any flight is flown.
    """
    request = EvaluateRequest(
        scenarios=scenario_names(scenarios),
        policies=tuple(policies),
        episodes=episodes,
        seed_start=seed_start,
        out=None if out is None else Path(out),
        ray=ray,
        html=html,
    )
    request.check()
    return run_evaluate(request, progress)


def run_evaluate(
    req: EvaluateRequest, progress: Callable[[int], Any] | None = None
) -> EvaluationResult:
    """Do the work of :func:`evaluate` for a checked request."""
    outputs = req.outputs()
    for where in req.folders().values():
        check_output_set(where, outputs, req.policy_files())
    seeds = list(range(req.seed_start, req.seed_start + req.episodes))
    names, policies = list(req.scenarios), list(req.policies)
    with runner(req.ray) as tasks:
        results = evaluate_scenarios(names, policies, seeds, progress=progress, runner=tasks)
    paths: list[Path] = []
    for s, where in req.folders().items():
        paths += _write(where, outputs, req.policy_files(), results[s], policies, seeds[0])
    return EvaluationResult(results, tuple(paths), retry_note(tasks))


def _write(
    folder: Path,
    outputs: tuple[str, ...],
    inputs: list[Path],
    results: dict[str, Any],
    policies: list[str],
    seed: int,
) -> list[Path]:
    """One scenario's output set, all replaced together; the paths written."""
    from agents.evaluation.plots import plot_evaluation

    with output_set(folder, outputs, inputs) as stage:
        write_text(stage / "results.json", json.dumps(jsonable(results), indent=2))
        plot_evaluation(results, stage / "evaluation.png")
        if reports.PAGE in outputs:
            traces = action_traces(results["scenario"], policies, seed)
            write_text(stage / reports.PAGE, reports.evaluate_page(jsonable(results), traces))
    return [folder / name for name in outputs]


def evaluation_table(results: dict[str, Any]) -> str:
    """Markdown: mean RMSE [95 % CI], paired difference vs fis [95 % CI], normalized score
    [paired bootstrap 95 % CI] when tuned_constant and privileged were evaluated, divergences."""
    anchors = results.get("normalized_score")
    lines = [
        f"{results['scenario']}: {len(results['seeds'])} flights (seeds {results['seeds'][0]}–"
        f"{results['seeds'][-1]})",
        "",
        "| policy | RMSE [nT] (95 % CI) | − fis [nT] (paired 95 % CI) | median abs log10 ROR "
        "| divergences |" + (" normalized score (95 % CI) |" if anchors else ""),
        "|---|---|---|---|---|" + ("---|" if anchors else ""),
    ]
    for name, r in results["policies"].items():
        lines.append(_table_row(name, r, anchors is not None))
    if len(results["seeds"]) < 2:
        lines += ["", "n/a: an interval needs at least 2 flights (--episodes ≥ 2)"]
    if anchors:
        headroom = _interval(anchors["headroom_nt_ci95"], ".3g")
        lines += [
            "",
            f"normalized score: 0 = {anchors['zero']}, 1 = {anchors['one']} "
            f"(headroom {anchors['headroom_nt_mean']:.3g} nT {headroom})"
            + (f"; {anchors['note']}" if anchors["note"] else ""),
        ]
    return "\n".join(lines) + "\n"


def _table_row(name: str, r: dict[str, Any], anchors: bool) -> str:
    """One policy's row of :func:`evaluation_table`."""
    diff = ""
    if "diff_vs_fis_nt_mean" in r and name != "fis":
        diff = f"{r['diff_vs_fis_nt_mean']:+.3g} {_interval(r['diff_vs_fis_ci95'], '+.3g')}"
    mean = f"{r['rmse_nt_mean']:.3g} {_interval(r['rmse_nt_ci95'], '.3g')}"
    score = ""
    if anchors and r.get("normalized_score") is not None:
        score = f" {r['normalized_score']:.3g} {_interval(r['normalized_score_ci95'], '.3g')} |"
    elif anchors:
        score = " n/a |"
    return (
        f"| {name} | {mean} | {diff} | {r['log_ror_abs_median']:.2g} | {r['divergences']} |{score}"
    )


def _interval(ci: Any, fmt: str) -> str:
    """``[lo, hi]``, or ``[n/a]`` when it could not be computed (a single flight)."""
    lo, hi = (float("nan") if v is None else float(v) for v in ci)
    return f"[{lo:{fmt}}, {hi:{fmt}}]" if math.isfinite(lo) and math.isfinite(hi) else "[n/a]"
