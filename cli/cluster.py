"""``jeanscv PATH... --dask tcp://HOST:8786``: the batch on an existing Dask cluster.

Only where the work runs changes. The inputs, their outputs, resuming (the jobs
``main._pending`` lets through), the progress line, the summary, the ``--report`` and the
exit status are the command's own, as in a local run; each input is a Dask task that
runs the ``-j`` workers' :func:`worker.process` on a cluster worker, sent and gathered by
:func:`jeanscv.run.distributed.run_tasks` (the API's ``run_on_dask`` runs on it too).

The inputs and the outputs must be on a file system the workers share, under the same
paths: tasks get absolute ones. A worker that dies under a task: the scheduler runs the
task again elsewhere, and one that keeps killing its workers fails that input alone
(``the task failed on the cluster: ...``). Its temporary files are removed when the run
ends, as a killed ``-j`` worker's are. Ctrl-C or SIGTERM cancels the tasks not yet
started; those running finish on their workers (their outputs are written atomically).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import queue as queues
from pathlib import Path

#: Why an input sent to the cluster was skipped there: its outputs appeared meanwhile.
#: A task runs again where its worker died, also one that died just after writing them.
MADE_MEANWHILE = "made meanwhile, by another jeanscv run or by a worker that died after writing it"


def describe(client, address: str) -> str:
    """``the Dask cluster at ADDRESS (2 workers, 4 threads)``, for the command's first line."""
    threads = client.nthreads()
    workers = len(threads)
    return (
        f"the Dask cluster at {address} ({workers} worker{'s' if workers != 1 else ''}, "
        f"{sum(threads.values())} threads)"
    )


def _absolute(path):
    return Path(os.path.abspath(path))


def _for_workers(job):
    """``job`` with absolute paths: a worker's working folder is not this process's."""
    return dataclasses.replace(
        job, path=_absolute(job.path), outputs={kind: _absolute(path) for kind, path in job.outputs.items()}
    )


def _options_for_workers(options):
    """``options`` as the workers need them: the garment resolved here, the mask and
    clicks files by absolute path."""
    from jeanscv.run.distributed import for_workers

    changes = {
        name: str(_absolute(value))
        for name in ("mask", "clicks")
        if isinstance(value := getattr(options, name), (str, os.PathLike))
    }
    return for_workers(options.replace(**changes))


def _as_named(outcome, job):
    """``outcome`` with the outputs named as this run names them (relative where its
    arguments were), so the lines and the report read as a local run's."""
    names = {str(_absolute(path)): str(path) for path in job.outputs.values()}
    outcome.output = names.get(outcome.output, outcome.output)
    outcome.written = [names.get(path, path) for path in outcome.written]
    return outcome


def run_on_cluster(queue, options, overwrite: bool, client) -> None:
    """Process the jobs of ``queue`` (a :class:`runs.WorkQueue`) as tasks on ``client``'s
    cluster, each outcome finished in ``queue`` as it comes back."""
    from jeanscv.run.distributed import run_tasks

    from .pool import _act_on_noted, _next_finished, _signals_noted
    from .runs import remove_leftovers_in
    from .worker import Outcome, process

    options = _options_for_workers(options)
    folders: set[Path] = set()

    def next_item():
        item = queue.next()
        if item is None:
            return None
        job, wait = item
        folders.update(path.parent for path in job.outputs.values())
        return item, (_for_workers(job), options, overwrite, wait)

    # As in the -j pool: Ctrl-C and SIGTERM are noted in the queue of finished tasks and
    # acted on as it is read, never raised inside the Dask client's locks.
    finished: queues.SimpleQueue = queues.SimpleQueue()
    queue.progress.start("on the Dask cluster")
    try:
        with (
            _signals_noted(finished),
            contextlib.closing(
                run_tasks(client, process, next_item, finished=finished, take=lambda: _next_finished(finished))
            ) as results,
        ):
            for (job, _), outcome, reason in results:
                if reason:
                    outcome = Outcome(job.index, job.display, "failed", error=reason)
                elif outcome.status == "skipped":  # its outputs did not exist when it was sent
                    outcome.error = MADE_MEANWHILE
                queue.finish(job, _as_named(outcome, job))
            _act_on_noted(finished)
    finally:
        for folder in folders:  # what workers that died mid-write left (a live writer's are locked and kept)
            remove_leftovers_in(folder)
