"""The ``-j`` worker processes: a pool of spawned workers, and what happens when one dies.

Each worker gets its share of the cores (``worker.init_worker``). A worker that dies
(killed, out of memory, a crash in a C library) breaks the pool, and with it every file
not yet finished; those run again rather than fail (:func:`run_parallel`).
"""

from __future__ import annotations

import os


def run_parallel(pending, options, overwrite: bool, workers: int, progress, outcomes) -> None:
    """Process ``pending`` in ``workers`` spawned processes, each with its share of the cores.

    A worker that dies (killed, out of memory, a crash in a C library) breaks the pool, and
    every file not yet finished with it. Those run again in a fresh pool; what a second
    broken pool leaves runs one file at a time, so that only a file that kills its worker
    every time fails (``worker process died``), not the files queued beside it.
    """
    from .runs import remove_leftovers

    def sweep(jobs) -> None:  # a dead worker could not remove its temporary file; its lock went with it
        remove_leftovers([path for job in jobs for path in job.outputs.values()])

    left = _pool_round(pending, options, overwrite, workers, progress, outcomes)
    if left:
        sweep(left)
        left = _pool_round(left, options, overwrite, workers, progress, outcomes)
    if left:
        sweep(left)
        _one_at_a_time(left, options, overwrite, progress, outcomes)
        sweep(left)


def _new_pool(workers: int):
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from jeanscv._command import worker_init

    threads = max(1, (os.cpu_count() or 1) // workers)
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=worker_init,
        initargs=(threads,),
    )


def _pool_round(jobs, options, overwrite: bool, workers: int, progress, outcomes) -> list:
    """Process ``jobs`` in a fresh pool; returns those a dying worker left unfinished."""
    from concurrent.futures import as_completed
    from concurrent.futures.process import BrokenProcessPool

    from .worker import Outcome, process_in_worker

    pool = _new_pool(workers)
    clean = False
    left = []
    try:
        futures = {pool.submit(process_in_worker, job, options, overwrite): job for job in jobs}
        progress.start(f"{workers} workers")
        for future in as_completed(futures):
            job = futures[future]
            try:
                outcome = future.result()
            except BrokenProcessPool:
                left.append(job)
                continue
            except Exception as exc:  # noqa: BLE001 - this file failed in its worker (unpicklable, say)
                outcome = Outcome(job.index, job.display, "failed", error=f"worker process died ({type(exc).__name__})")
            outcomes[job.index] = outcome
            progress.finish(outcome)
        clean = True
    finally:
        if clean:
            pool.shutdown(wait=True)
        else:
            _stop_pool(pool)
    return sorted(left, key=lambda job: job.index)


def _one_at_a_time(jobs, options, overwrite: bool, progress, outcomes) -> None:
    """Process ``jobs`` one by one in a single worker: a file whose worker dies fails alone."""
    from concurrent.futures.process import BrokenProcessPool

    from .worker import Outcome, process_in_worker

    pool = None
    try:
        for job in jobs:
            pool = pool or _new_pool(1)
            try:
                outcome = pool.submit(process_in_worker, job, options, overwrite).result()
            except BrokenProcessPool:
                outcome = Outcome(job.index, job.display, "failed", error="worker process died (BrokenProcessPool)")
                pool.shutdown(wait=True)
                pool = None
            except Exception as exc:  # noqa: BLE001 - as in _pool_round
                outcome = Outcome(job.index, job.display, "failed", error=f"worker process died ({type(exc).__name__})")
            outcomes[job.index] = outcome
            progress.finish(outcome)
    except BaseException:
        if pool is not None:
            _stop_pool(pool)
            pool = None
        raise
    finally:
        if pool is not None:
            pool.shutdown(wait=True)


def _stop_pool(pool) -> None:
    """Cancel queued files and stop the workers; a worker mid-file removes its temporary file."""
    processes = list(getattr(pool, "_processes", {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()  # SIGTERM: see worker.init_worker
    for process in processes:
        process.join(timeout=10)
        if process.is_alive():
            process.kill()
