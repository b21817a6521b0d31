"""Run :func:`jeanscv.pipeline.apply_jeans` over many files on a Dask cluster.

Needs the optional dependency ``dask[distributed]`` (``pip install jeanscv[dask]``),
imported only when it is used. Each input is one task; the task decodes, fits and
composites on a worker and writes its outputs itself (atomically), so the inputs and
the outputs must be on a file system the workers share with the driver. Only small
records travel back to the driver, which writes the JSONL report. One input failing
(bad file, diverged fit, a worker dying) never stops the others.

:func:`run_on_dask` is the API's runner. Its parts serve the command's ``--dask`` too
(``jeanscv_cli.cluster``), which runs its own per-input work on the workers:
:func:`connect` (a scheduler's address to a client, or one clear error),
:func:`for_workers` (options the workers can use as they are) and :func:`run_tasks`
(tasks kept flowing to the cluster, each finished or lost one reported as it ends).
"""

from __future__ import annotations

import json
import os
import queue
import socket
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..errors import JeansError
from ..options import JeansOptions
from .runner import encode_picture, failure_reason, one_line, report_text

#: Seconds to wait for a scheduler named by its address before giving up on it.
CONNECT_TIMEOUT = 10.0


def _dask_distributed():
    try:
        import distributed
    except ImportError:
        raise JeansError("running on Dask needs dask[distributed]: install jeanscv[dask]") from None
    return distributed


def output_paths(paths: Iterable[str | os.PathLike], output_dir: str | os.PathLike) -> list[tuple[Path, Path, Path]]:
    """``(input, picture, report)`` for each distinct input: ``<stem>.jeans.<ext>`` and
    ``<stem>.jeans.json`` in ``output_dir``.

    The same file named twice is one input. When two inputs would share outputs
    (``dog.png`` and ``dog.svg``), the later keeps its extension in the name
    (``dog.svg.jeans.png``), as the CLI does.
    """
    from ..io.write import output_extension

    folder = Path(output_dir)
    seen: set[str] = set()
    claimed: set[str] = set()
    out = []
    for raw in paths:
        path = Path(raw)
        key = os.path.normcase(os.path.abspath(path))
        if key in seen:
            continue
        seen.add(key)
        ext = output_extension(path)
        base = path.stem
        if (
            os.path.normcase(str(folder / f"{base}.jeans{ext}")) in claimed
            or os.path.normcase(str(folder / f"{base}.jeans.json")) in claimed
        ):
            base = path.name
        picture, report = folder / f"{base}.jeans{ext}", folder / f"{base}.jeans.json"
        claimed.update({os.path.normcase(str(picture)), os.path.normcase(str(report))})
        out.append((path, picture, report))
    return out


def process_one(source: str, picture: str, report: str, options: JeansOptions, overwrite: bool = True) -> dict:
    """One task: ``apply_jeans(source, options)``, then write the picture and its JSON report.

    Never raises for a bad input: returns the record ``{"status": "ok"|"failed"|"skipped",
    "input", "output", "report", "error", "seconds", ...}``. Both files are encoded before
    either is written, so a failure leaves no output behind.
    """
    from ..io.write import atomic_write_bytes, write_text
    from ..pipeline import apply_jeans

    began = time.perf_counter()
    record: dict[str, Any] = {"status": "ok", "input": source, "output": picture, "report": report, "error": ""}
    try:
        if not overwrite and os.path.exists(picture) and os.path.exists(report):
            record.update(status="skipped", error="its outputs exist already")
        else:
            result = apply_jeans(source, options)
            data = encode_picture(picture, result.image, result)
            text = report_text(result, source, picture)
            atomic_write_bytes(picture, data)
            write_text(report, text)
            fit = result.fit
            record.update(
                kind=result.kind,
                silhouette_method=result.silhouette.method,
                garment=fit.garment.name,
                device=fit.device,
                fit_seconds=round(fit.seconds, 3),
                objective=float(fit.objective),
                paper_total=float(fit.paper_total),
            )
    except Exception as exc:  # noqa: BLE001 - every failure becomes this input's one line
        record.update(status="failed", output="", report="", error=failure_reason(exc))
    record["seconds"] = round(time.perf_counter() - began, 3)
    try:
        from distributed import get_worker

        record["worker"] = get_worker().address
    except (ImportError, ValueError):
        pass  # called outside a Dask worker
    return record


def for_workers(options: JeansOptions) -> JeansOptions:
    """``options`` with the garment resolved here on the driver: a ``.toml`` or plugin
    garment need not exist on the workers."""
    from ..plugins import get_garment

    return options.replace(garment=get_garment(options.garment))


def _checked_options(apply_options: dict[str, Any]) -> JeansOptions:
    """``apply_jeans``'s options by name, checked, made ready for the workers."""
    unknown = [name for name in apply_options if name not in JeansOptions.names()]
    if unknown:
        raise JeansError(f"bad apply_jeans option: got an unexpected keyword argument {unknown[0]!r}")
    return for_workers(JeansOptions(**apply_options))


def _probe(distributed: Any, address: str, timeout: float) -> None:
    """Raise JeansError unless a TCP connection to the scheduler's ``address`` opens
    within ``timeout`` seconds (transports that are not TCP are left to the client).

    A client that cannot connect raises only after its whole timeout, even where the
    port refuses at once, and the half-made client then prints a traceback as the
    interpreter exits; the probe says why at once, and no client is made."""
    try:
        scheme, location = distributed.comm.parse_address(address)
        if scheme not in ("tcp", "tls", "ws", "wss"):
            return
        host, port = distributed.comm.addressing.parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise JeansError(f"not a Dask scheduler address: {address!r} ({one_line(exc)})") from None
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except TimeoutError:
        raise JeansError(f"cannot reach the Dask scheduler at {address}: no answer within {timeout:g} s") from None
    except OSError as exc:
        reason = (exc.strerror or str(exc)).lower()
        raise JeansError(f"cannot reach the Dask scheduler at {address}: {reason}") from None


def connect(address: str, timeout: float | None = None) -> Any:
    """A ``distributed.Client`` of the scheduler at ``address`` (``tcp://HOST:8786``),
    not made the default client; the caller closes it.

    Raises JeansError, one line naming ``address``, where ``dask[distributed]`` is not
    installed, the address is not one, or the scheduler cannot be reached within
    ``timeout`` seconds (default :data:`CONNECT_TIMEOUT`).
    """
    distributed = _dask_distributed()
    timeout = CONNECT_TIMEOUT if timeout is None else timeout
    _probe(distributed, address, timeout)
    try:
        return distributed.Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise JeansError(f"cannot reach the Dask scheduler at {address}: {one_line(exc)}") from None
    except (ValueError, TypeError) as exc:
        raise JeansError(f"not a Dask scheduler address: {address!r} ({one_line(exc)})") from None


@contextmanager
def _dask_client(distributed: Any, client: Any) -> Iterator[Any]:
    """``client`` (a scheduler's address is connected to), else the current client, else a
    local cluster started for this call; what this call made is closed when it ends."""
    own_client = None
    if isinstance(client, str):
        own_client = client = connect(client)
    elif client is None:
        try:
            client = distributed.get_client()
        except ValueError:
            own_client = client = distributed.Client(processes=True)
    try:
        yield client
    finally:
        if own_client is not None:
            own_client.close()
            if own_client.cluster is not None:
                own_client.cluster.close()


def run_tasks(
    client: Any,
    task: Callable,
    next_item: Callable[[], tuple[Any, tuple] | None],
    ahead: int | None = None,
    finished: queue.SimpleQueue | None = None,
    take: Callable[[], Any] | None = None,
    **kwargs: Any,
) -> Iterator[tuple[Any, Any, str]]:
    """Run ``task(*args, **kwargs)`` on ``client``'s cluster for each ``(item, args)`` that
    ``next_item()`` gives, and yield ``(item, result, "")`` as each task finishes, or
    ``(item, None, reason)`` where it was lost (its worker died more often than the
    scheduler retries a task, say) or raised.

    ``next_item()`` returning None means nothing more for now: it is asked again as
    tasks finish, and the iteration ends when it gives nothing and no task is left. At
    most ``ahead`` tasks (default: twice the cluster's threads) are out at once, so items
    are made as they are needed and a big batch is not all queued up front. Finished
    tasks' futures are put in ``finished`` (default: a new queue) from the client's
    thread and taken by ``take()`` (default: its ``get``); the command passes its own,
    which acts on the signals it notes in that queue. When the caller stops early (an
    interrupt), the tasks not yet finished are cancelled: those still queued never
    start, running ones end on their worker.
    """
    if ahead is None:
        ahead = max(2, 2 * sum(client.nthreads().values()))
    finished = queue.SimpleQueue() if finished is None else finished
    take = finished.get if take is None else take
    running: dict[Any, Any] = {}  # future -> item
    try:
        while True:
            while len(running) < ahead and (made := next_item()) is not None:
                item, args = made
                future = client.submit(task, *args, pure=False, **kwargs)
                running[future] = item
                future.add_done_callback(finished.put)
            if not running:
                return
            future = take()
            if future not in running:
                continue  # a future of an earlier run on the same queue
            item = running.pop(future)
            try:
                result, reason = future.result(), ""
            except Exception as exc:  # noqa: BLE001 - a lost task fails only its own item
                result, reason = None, f"the task failed on the cluster: {failure_reason(exc)}"
            yield item, result, reason
    finally:
        if running:
            client.cancel(list(running))


def _run_jobs(client: Any, jobs: list[tuple[Path, Path, Path]], options: JeansOptions, overwrite: bool) -> list[dict]:
    """One :func:`process_one` task per job on ``client``; the records in job order, a
    task lost on the cluster (a worker dying) failing only its own input."""
    items = ((index, tuple(map(str, job))) for index, job in enumerate(jobs))
    records: dict[int, dict] = {}
    for index, record, reason in run_tasks(
        client, process_one, lambda: next(items, None), options=options, overwrite=overwrite
    ):
        if reason:
            record = {
                "status": "failed",
                "input": str(jobs[index][0]),
                "output": "",
                "report": "",
                "error": reason,
                "seconds": 0.0,
            }
        records[index] = record
    return [records[index] for index in sorted(records)]


def run_on_dask(
    paths: Iterable[str | os.PathLike],
    output_dir: str | os.PathLike,
    client: Any = None,
    report: str | os.PathLike | None = None,
    overwrite: bool = True,
    **apply_options: Any,
) -> list[dict]:
    """Apply jeans to every path on a Dask cluster; one record per distinct input, in order.

    Args:
        paths: input files (photos, RAW, silhouette PNGs, SVGs) the workers can read.
        output_dir: where ``<stem>.jeans.<ext>`` and ``<stem>.jeans.json`` go (created).
        client: a ``distributed.Client``, or a scheduler's address (``tcp://HOST:8786``,
            connected to for this call, see :func:`connect`); None uses the current
            client, or starts a local cluster for this call and closes it afterwards.
        report: optional path of the JSONL report (one record per line, input order).
        overwrite: False skips inputs whose two outputs exist (a resumed run).
        apply_options: the options of :func:`jeanscv.pipeline.apply_jeans`, by name
            (:class:`jeanscv.options.JeansOptions`: ``garment``, ``preset``, ``iterations``,
            ``seed``, ...), checked here. The garment is resolved here, so a ``.toml``
            garment or a plugin garment need only exist on the driver; silhouette plugins
            must be installed on the workers.

    Returns:
        The records of :func:`process_one` (with ``worker``, the address it ran on).
    """
    distributed = _dask_distributed()
    options = _checked_options(apply_options)
    jobs = output_paths(paths, output_dir)
    try:
        Path(output_dir).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise JeansError(f"cannot create output folder: {(exc.strerror or str(exc)).lower()}") from None
    with _dask_client(distributed, client) as running:
        records = _run_jobs(running, jobs, options, overwrite)

    if report is not None:
        from ..io.write import write_text

        write_text(report, "".join(json.dumps(r, sort_keys=True) + "\n" for r in records))
    return records


__all__ = ["CONNECT_TIMEOUT", "connect", "for_workers", "output_paths", "process_one", "run_on_dask", "run_tasks"]
