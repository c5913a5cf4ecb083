"""The design search of ``tdpcr-optim`` on a Dask ``distributed`` cluster.

``python -m tdpcr.optim CONFIG.ron --out DIR [--scheduler tcp://HOST:PORT | --local-workers N]
[--budget-evals N] [--seed S] [--resume]`` writes the same run directory as ``tdpcr-optim``
(``evaluations.jsonl``, ``run.ron``, designs, ``pareto.csv``, ``report.md``, figures).

The algorithm is the Rust one (``DesignSearch``: CMA-ES ask/tell, the log, resume, the
outputs); this driver only ships each generation's candidates to the workers
(``SearchProblem.evaluate``, a pure function with the GIL released) and tells the results
back. Only the driver writes the log, in candidate order, once all of a generation's
results are in: a worker lost mid-evaluation makes Dask run its task elsewhere (its
result is then told once), and a driver killed mid-generation loses only that
generation's unlogged evaluations; ``--resume`` replays the logged ones without
evaluating them again. Without ``--scheduler`` a ``LocalCluster`` of N single-threaded
worker processes runs on this machine. Every worker needs this package installed.
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
import sys
import time
from typing import Optional, Sequence

from ._tdpcr import DesignSearch, SearchProblem

__all__ = ["DesignSearch", "SearchProblem", "evaluate", "run", "main"]

#: Times Dask re-runs a task that raised (a lost worker is rescheduled regardless).
RETRIES = 2


@functools.lru_cache(maxsize=4)
def _problem(problem: str) -> SearchProblem:
    return SearchProblem(problem)


def evaluate(problem: str, candidate: str) -> str:
    """The result (JSON) of one candidate (JSON) of the search ``problem`` (RON text of
    ``DesignSearch.problem``); the task each worker runs. The parsed problem is cached
    per process."""
    return _problem(problem).evaluate(candidate)


def _task_keys(problem: str, candidates: Sequence[str]) -> list:
    """Deterministic task keys: one per candidate of this problem (same key, same
    result), so a resubmitted candidate is never a second, different task."""
    run = hashlib.sha1(problem.encode()).hexdigest()[:16]
    return [f"tdpcr-evaluate-{run}-{json.loads(c)['id']}" for c in candidates]


def run(search: DesignSearch, client, progress=None, task=evaluate) -> int:
    """Runs ``search`` to its end on the Dask ``client``: per generation, the candidates
    are mapped to the workers (``task(problem, candidate)``, by default
    :func:`evaluate`), gathered, and told back. ``progress`` gets a line per
    generation. Returns the number of evaluations done on the cluster."""
    problem = search.problem
    evaluations = 0
    generation = 0
    while True:
        candidates = search.ask()
        if not candidates:
            return evaluations
        start = time.monotonic()
        futures = client.map(
            task,
            [problem] * len(candidates),
            candidates,
            key=_task_keys(problem, candidates),
            retries=RETRIES,
            pure=False,
        )
        try:
            results = client.gather(futures)
        finally:
            client.cancel(futures)
        search.tell(results)
        evaluations += len(results)
        if progress is not None:
            progress(
                f"batch {generation}: {len(results)} candidates evaluated in "
                f"{time.monotonic() - start:.1f} s ({evaluations} in this run)"
            )
        generation += 1


def _bounded_int(low: int, high: int):
    """An argparse type: an integer in [low, high] (argparse reports others, exit 2;
    a negative --seed raised OverflowError in the search, a traceback)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r}: expected an integer") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{value}: expected {low} to {high}")
        return value

    return parse


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m tdpcr.optim",
        description="The design search of tdpcr-optim with the candidates evaluated on a "
        "Dask distributed cluster; writes the same run directory as tdpcr-optim.",
    )
    p.add_argument("config", help="search configuration (RON), e.g. optim/default.ron")
    p.add_argument("--out", required=True, help="output directory (created if missing)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", help="address of a running scheduler, tcp://HOST:PORT")
    where.add_argument(
        "--local-workers",
        type=int,
        default=None,
        metavar="N",
        help="without --scheduler: a LocalCluster of N single-threaded worker processes "
        "(default: the number of cores)",
    )
    p.add_argument(
        "--budget-evals",
        type=_bounded_int(1, 2**64 - 1),
        metavar="N",
        help="overrides budget.evaluations",
    )
    p.add_argument("--seed", type=_bounded_int(0, 2**64 - 1), metavar="S", help="overrides seed")
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    return p


def main(argv: Optional[Sequence[str]] = None) -> int:
    """The command line; exit codes as ``tdpcr-optim``'s (0 done, 1 failed, 2 bad input)."""
    args = _parser().parse_args(argv)
    if args.local_workers is not None and args.local_workers < 1:
        print(f"error: --local-workers {args.local_workers}: expected at least 1", file=sys.stderr)
        return 2
    try:
        search = DesignSearch(
            args.config,
            args.out,
            seed=args.seed,
            budget_evals=args.budget_evals,
            resume=args.resume,
        )
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1

    from distributed import Client, LocalCluster

    def say(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    cluster = None
    try:
        if args.scheduler:
            client = Client(args.scheduler)
        else:
            import os

            n = args.local_workers or os.cpu_count() or 1
            # One evaluation per worker process, each sweep on one thread (unless
            # RAYON_NUM_THREADS says otherwise): N workers use N cores.
            rayon = os.environ.get("RAYON_NUM_THREADS", "1")
            cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                env={"RAYON_NUM_THREADS": rayon},
            )
            client = Client(cluster)
        with client:
            workers = len(client.scheduler_info().get("workers", {}))
            say(f"tdpcr.optim: {workers} workers at {client.scheduler.address}; log {args.out}")
            run(search, client, say)
        say(f"search ended: {search.termination}")
        summary = search.finish(" ".join(["python -m tdpcr.optim", *(argv or sys.argv[1:])]), workers)
    except (OSError, RuntimeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    finally:
        if cluster is not None:
            cluster.close()
    best = summary["best_composite"]
    print(
        f"{summary['candidates']} candidates ({summary['evaluated']} evaluated now), "
        f"{summary['pareto']} Pareto-optimal, {summary['dominating_reference']} dominate the "
        f"reference; best composite "
        + ("none" if best is None else f"{best[0]:.4f} (#{best[1]})")
    )
    for f in map(str, summary["files"]):
        if not f.endswith(".svg"):
            print(f)
    return 0


if __name__ == "__main__":
    # Run the package's module, not this `__main__` copy, so that the workers unpickle
    # `tdpcr.optim.evaluate` by reference.
    from tdpcr.optim import main as _main

    sys.exit(_main())
