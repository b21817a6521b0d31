"""Run :func:`jeanscv.pipeline.apply_jeans` over many files on a Dask cluster.

Needs the optional dependency ``dask[distributed]`` (``pip install jeanscv[dask]``),
imported only when :func:`run_on_dask` is called. Each input is one task; the task
decodes, fits and composites on a worker and writes the picture and its JSON report
itself (atomically), so the inputs and ``output_dir`` must be on a file system the
workers share with the driver. Only small records travel back to the driver, which
writes the JSONL report. One input failing (bad file, diverged fit, a worker dying)
never stops the others.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..errors import JeansError
from ..options import JeansOptions
from .runner import encode_picture, failure_reason, report_text

#: Extensions that keep their format in the output; everything else gets ``.png``,
#: except RAW files, whose developed photo is written as ``.jpg`` (the CLI's rule).


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


def _checked_options(apply_options: dict[str, Any]) -> JeansOptions:
    """``apply_jeans``'s options by name, checked, with the garment resolved here on the
    driver (a ``.toml`` or plugin garment need not exist on the workers)."""
    from ..plugins import get_garment

    unknown = [name for name in apply_options if name not in JeansOptions.names()]
    if unknown:
        raise JeansError(f"bad apply_jeans option: got an unexpected keyword argument {unknown[0]!r}")
    options = JeansOptions(**apply_options)
    return options.replace(garment=get_garment(options.garment))


@contextmanager
def _dask_client(distributed: Any, client: Any) -> Iterator[Any]:
    """``client``, else the current client, else a local cluster started for this call
    and closed when it ends."""
    own_client = None
    if client is None:
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


def _run_jobs(client: Any, jobs: list[tuple[Path, Path, Path]], options: JeansOptions, overwrite: bool) -> list[dict]:
    """One :func:`process_one` task per job on ``client``; the records in job order, a
    task lost on the cluster (a worker dying) failing only its own input."""
    futures = client.map(
        process_one,
        [str(p) for p, _, _ in jobs],
        [str(pic) for _, pic, _ in jobs],
        [str(rep) for _, _, rep in jobs],
        options=options,
        overwrite=overwrite,
        pure=False,
    )
    records = []
    for (path, _, _), future in zip(jobs, futures):
        try:
            record = future.result()
        except Exception as exc:  # noqa: BLE001 - a lost worker fails only its inputs
            record = {
                "status": "failed",
                "input": str(path),
                "output": "",
                "report": "",
                "error": f"the task failed on the cluster: {failure_reason(exc)}",
                "seconds": 0.0,
            }
        records.append(record)
    return records


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
        client: a ``distributed.Client``; None uses the current one, or starts a local
            cluster for this call and closes it afterwards.
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


__all__ = ["output_paths", "process_one", "run_on_dask"]
