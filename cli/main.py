"""The ``jeanscv`` command: put jeans on every silhouette and photo you name.

Only click and the lists of allowed values (:mod:`jeanscv.options`, :mod:`jeanscv.device`)
are imported at module level: ``jeanscv --help`` and ``--version`` must not load numpy,
torch, kornia, OpenCV or rawpy. Everything else is imported inside the command.
"""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path

import click

from jeanscv import __version__
from jeanscv.device import BACKENDS, DEVICES
from jeanscv.options import DETECTORS, KINDS, OBJECTS, POSTURES, STYLES, SUBJECTS, JeansOptions

from . import params
from .sections import SectionedCommand

#: The library's defaults, which the command's options show and use (``--device`` is ``auto`` here).
DEFAULTS = JeansOptions()

EPILOG = """\b
Examples:
  jeanscv dog.svg                       dog.jeans.png (the paper's figure)
  jeanscv cat.jpg --style flat          cat.jeans.jpg, jeans in the paper's blue
  jeanscv photos/ -r -o out/ -j 2       every image below photos/, mirrored under out/
  jeanscv photos/ -r -o out/ --dask tcp://HOST:8786   the same on a Dask cluster's workers
  jeanscv 'shots/*.NEF' --format webp   RAW files, globs expanded by jeanscv itself
  jeanscv cat.jpg --top "how would" --bottom "a cat wear jeans" --side-by-side
  jeanscv horse.png --json --svg --gif  sidecars: report, vector overlay, animation
  jeanscv cat.jpg --mask cat_mask.png   your own mask instead of the segmentation
  jeanscv pets.jpg --objects all        jeans on every separate object
  jeanscv family.jpg --subject person    the person, not the dog beside them
  jeanscv pets.jpg --point 420,310      jeans on the object under that pixel (a click)
  jeanscv pets.jpg --point 420,310 --background-point 90,40   ...and not on that
  jeanscv pets.jpg --box 300,180,640,470   jeans on the thing in that box (x0,y0,x1,y1)
  jeanscv pets.jpg --clicks pets.clicks.json                   replay saved clicks
  jeanscv car.jpg --posture any         jeans in any posture, lying ones too
  jeanscv dog.gif                       dog.jeans.gif: the jeans follow the dog frame by frame
  jeanscv clip.mp4 --format gif         clip.jeans.gif (MP4, MOV, WebM, MKV, GIF, animated WebP/PNG)
  jeanscv serve [FOLDER]                a local web page: drop a photo, click the subject
                                        (see 'jeanscv serve --help')

\b
Outputs are written next to each input as NAME.jeans.EXT (or under -o DIR).
Existing outputs are skipped unless --overwrite, so an interrupted run resumes.
A photo with clicks saved beside it (NAME.clicks.json, by jeanscv serve) uses them.
Exit status: 0 all done, 1 some input failed, 2 usage error, 130/143 interrupted.
"""


@click.command(
    cls=SectionedCommand,
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
    epilog=EPILOG,
)
@click.argument("paths", nargs=-1, metavar="PATH...")
@click.option(
    "-o",
    "--output-dir",
    type=click.Path(file_okay=False, path_type=Path),
    help="Write outputs here, mirroring the input folders (default: next to each input).",
)
@click.option("-r", "--recursive", is_flag=True, help="Descend into subfolders of folder arguments.")
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["png", "jpg", "webp", "gif", "mp4"]),
    help="Output format (default: photos keep theirs, RAW -> jpg, silhouettes -> png; clips: GIF -> gif, "
    "videos -> mp4). gif, mp4 and webp convert clips; a still becomes a one-frame gif or mp4.",
)
@click.option("--overwrite", is_flag=True, help="Redo inputs whose outputs already exist.")
@click.option("--json", "want_json", is_flag=True, help="Also write NAME.jeans.json: the fit report.")
@click.option("--svg", "want_svg", is_flag=True, help="Also write NAME.jeans.svg: silhouette and jeans as vectors.")
@click.option("--gif", "want_gif", is_flag=True, help="Also write NAME.jeans.gif: the optimisation, animated.")
@click.option(
    "--gif-frames",
    type=click.IntRange(2, 500),
    default=DEFAULTS.gif_frames,
    show_default=True,
    help="Most frames in the --gif animation.",
)
@click.option(
    "--report",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write a JSON-lines report, one line per input, to this file.",
)
@click.option("--preset", default=DEFAULTS.preset, show_default=True, help="Fitting preset (see --list-presets).")
@click.option(
    "--posture",
    type=click.Choice(POSTURES),
    default=DEFAULTS.posture,
    show_default=True,
    help="upright: the garment hangs down unless no upright fit passes the rule checks; "
    "any: every posture competes (the algorithm's wilder answers).",
)
@click.option(
    "--garment",
    default=DEFAULTS.garment,
    show_default=True,
    help="Garment: a name (see --list-garments) or a .toml file.",
)
@click.option(
    "--iterations", type=click.IntRange(0), default=DEFAULTS.iterations, show_default=True, help="Optimiser steps."
)
@click.option(
    "--seed", type=int, default=DEFAULTS.seed, show_default=True, help="Random seed (same seed, same result)."
)
@click.option("--starts", type=click.IntRange(1), help="Initial placements tried (default: the preset's).")
@click.option(
    "--kind",
    type=click.Choice(KINDS),
    default=DEFAULTS.kind,
    show_default=True,
    help="Treat inputs as silhouette drawings or photos.",
)
@click.option(
    "--silhouette",
    "silhouette_method",
    default=DEFAULTS.silhouette_method,
    show_default=True,
    callback=params.check_silhouette,
    help="How to cut the object out of a photo: auto, alpha, threshold, grabcut, or a plugin's name.",
)
@click.option("--threshold", type=click.FloatRange(0, 255), help="Grey level for --silhouette threshold.")
@click.option("--mask", type=click.Path(exists=True, dir_okay=False), help="Mask image for a single input.")
@click.option(
    "--rect",
    "rect_box",
    callback=params.rect_as_box,
    metavar="X,Y,W,H",
    hidden=True,
    help="The old name of --box, as X,Y,W,H.",
)
@click.option(
    "--objects",
    type=click.Choice(OBJECTS),
    default=DEFAULTS.objects,
    show_default=True,
    help="Jeans on the main subject only, or on every separate object of a photo.",
)
@click.option(
    "--subject",
    type=click.Choice(SUBJECTS),
    default=DEFAULTS.subject,
    show_default=True,
    help="What automatic finding looks for in a photo: auto (an animal rather than the person "
    "beside it), animal, person, object (the most salient thing), or an animal class (dog, cat, ...).",
)
@click.option(
    "--detector",
    type=click.Choice(DETECTORS),
    default=DEFAULTS.detector,
    show_default=True,
    help="How automatic finding knows what is in a photo: auto (the small object detector shipped "
    "with jeanscv finds the animal's box) or none (classical cues alone).",
)
@click.option(
    "--point",
    "points",
    multiple=True,
    callback=params.parse_points,
    metavar="X,Y",
    help="A click on the object that should wear the jeans (pixels of the photo; repeatable: "
    "more clicks refine the same object; one input).",
)
@click.option(
    "--background-point",
    "background_points",
    multiple=True,
    callback=params.parse_points,
    metavar="X,Y",
    help="A click on something that is not that object (repeatable; alone: the automatic subject "
    "minus what it takes away; one input).",
)
@click.option(
    "--box",
    "box",
    callback=params.parse_box,
    metavar="X0,Y0,X1,Y1",
    help="A box around the object that should wear the jeans (pixels of the photo; alone or with "
    "--point and --background-point; one input).",
)
@click.option(
    "--clicks",
    "clicks",
    type=click.Path(dir_okay=False, path_type=Path),
    metavar="FILE.json",
    help="Replay a clicks file (one or several objects; the web page saves them; one input).",
)
@click.option(
    "--style",
    type=click.Choice(STYLES),
    default=DEFAULTS.style,
    show_default=True,
    help="denim texture, or the paper's flat blue.",
)
@click.option("--clip/--no-clip", default=DEFAULTS.clip, show_default=True, help="Paint jeans only on the object.")
@click.option(
    "--top",
    metavar="TEXT",
    help="Meme caption along the top; 'auto': \"how would a cat\" (the detected animal, where its class "
    'is sure; else "how would this"), with "wear jeans?" along the bottom unless --bottom is given.',
)
@click.option("--bottom", metavar="TEXT", help="Meme caption along the bottom.")
@click.option("--side-by-side", is_flag=True, help="Output the original and the result side by side.")
@click.option(
    "--max-pixels",
    type=click.IntRange(1),
    default=DEFAULTS.max_pixels,
    show_default=True,
    help="Refuse images larger than this.",
)
@click.option(
    "--max-frames",
    type=click.IntRange(1),
    default=DEFAULTS.max_frames,
    show_default=True,
    help="Refuse clips with more frames than this.",
)
@click.option("--raw-half-size", is_flag=True, help="Decode RAW files at half size, for speed (default: full size).")
@click.option(
    "--raw-full-size",
    is_flag=True,
    hidden=True,
    expose_value=False,
    help="Accepted for compatibility: RAW files decode at full size by default.",
)
@click.option("--device", type=click.Choice(DEVICES), default="auto", show_default=True, help="Where to fit.")
@click.option(
    "--backend",
    type=click.Choice(("auto", *BACKENDS)),
    default="auto",
    show_default=True,
    help="Fitting code on the CPU: fast (compiled kernel) or torch (the reference); "
    "auto: $JEANSCV_BACKEND, else fast when numba is installed.",
)
@click.option(
    "-j",
    "--jobs",
    type=click.IntRange(1),
    help="Worker processes for many inputs (default: one per core, as memory allows).",
)
@click.option(
    "--dask",
    metavar="ADDRESS",
    help="Run the batch on the Dask cluster whose scheduler is at ADDRESS (tcp://HOST:8786) "
    "instead of local workers; inputs and outputs must be on a file system the workers share "
    "(needs jeanscv[dask]).",
)
@click.option("-q", "--quiet", is_flag=True, help="Print errors only.")
@click.option("-v", "--verbose", is_flag=True, help="Print the silhouette method, device and losses per file.")
@click.option(
    "--list-presets",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=params.list_presets,
    help="List the presets and exit.",
)
@click.option(
    "--list-garments",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=params.list_garments,
    help="List the garments and exit.",
)
@click.option(
    "--clear-cache",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=params.clear_cache,
    help="Remove the compiled fit kernels (every version's) from the per-user cache and exit.",
)
@click.version_option(__version__, "--version", prog_name="jeanscv", message="%(prog)s %(version)s")
@click.pass_context
def cli(ctx: click.Context, paths: tuple[str, ...], **kw) -> None:
    """Put jeans on the objects in PATH... (SVG or PNG silhouettes, photos, camera RAW, clips).

    PATH may be files, folders (with -r, their subfolders too) and glob patterns.
    How would this thing wear jeans? (Pagurek's jalgorithm, SIGBOVIK 2023.)
    """
    from .interrupts import usual_interrupts
    from .worker import fewer_collections, skip_exit_collection

    skip_exit_collection()
    try:
        usual_interrupts()
        with fewer_collections():
            code = _main(ctx, paths, **kw)
    except KeyboardInterrupt:
        code = 130
    ctx.exit(code)


def _usage(message: str) -> click.UsageError:
    return click.UsageError(message)


def _main(
    ctx: click.Context,
    paths: tuple[str, ...],
    *,
    output_dir,
    recursive,
    fmt,
    overwrite,
    want_json,
    want_svg,
    want_gif,
    report,
    device,
    backend,
    jobs,
    dask,
    quiet,
    verbose,
    rect_box,
    **values,
) -> int:
    """The command; ``values`` are the per-input options (:class:`JeansOptions`' names)."""
    if not paths:
        raise _usage("no PATH given: name files, folders or patterns (see --help)")
    if rect_box is not None:
        if values["box"] is not None:
            raise _usage("--rect is the old name of --box: give --box alone")
        values["box"] = rect_box
    if dask is not None and jobs is not None:
        raise _usage("-j sets local worker processes; with --dask the cluster's workers do the work")
    if dask is None:
        _start_workers_early(list(paths), jobs)
    from jeanscv.device import resolve_backend, resolve_device
    from jeanscv.errors import JeansError
    from jeanscv.fitting._fast import kernel_cache_dir, kernels_cached
    from jeanscv.run.runner import one_line

    from .discover import collect
    from .progress import Progress

    _check_names(ctx, values)
    try:
        device = resolve_device(device)
        backend = resolve_backend(None if backend == "auto" else backend, device)
    except JeansError as exc:
        click.echo(f"jeanscv: {one_line(exc)}", err=True)
        return 2

    extras = tuple(name for name, wanted in (("json", want_json), ("svg", want_svg), ("gif", want_gif)) if wanted)
    if want_gif and fmt == "gif":
        raise _usage("--gif and --format gif would both write NAME.jeans.gif: choose one")
    found = collect(list(paths), recursive, output_dir, fmt, extras)
    single = found.total + len(found.problems) == 1
    if values["mask"] is not None and not single:
        raise _usage("--mask needs exactly one input image")
    if values["points"] and not single:
        raise _usage("--point needs exactly one input image (its pixels are that image's)")
    if values["box"] is not None and not single:
        raise _usage("--box needs exactly one input image (its pixels are that image's)")
    if values["background_points"] and not single:
        raise _usage("--background-point needs exactly one input image (its pixels are that image's)")
    if values["clicks"] is not None and not single:
        raise _usage("--clicks needs exactly one input image (its pixels are that image's)")
    options = JeansOptions(**values, device=device, backend=backend)
    cluster = None
    if dask is not None:
        from jeanscv.run.distributed import connect

        try:
            cluster = connect(dask)
        except JeansError as exc:
            click.echo(f"jeanscv: {one_line(exc)}", err=True)
            return 2
    try:
        progress = Progress(found.total, quiet=quiet, verbose=verbose)
        progress.serve_hint = _serve_hint(paths)
        noun = "input" if found.total == 1 else "inputs"
        if cluster is not None:
            from .cluster import describe

            workers, where = 0, describe(cluster, dask)
        else:
            workers, why = _workers(jobs, found.total)
            where = f"{workers} worker{'s' if workers > 1 else ''} ({why})"
        progress.info(
            f"jeanscv {__version__}: {found.total} {noun}, {where}, device {device} ({backend}), "
            f"preset {options.preset}, {options.iterations} iterations"
        )
        if cluster is None and backend == "fast" and kernels_cached() is False:
            progress.info(
                "compiling the fit kernels for this installation, once (about 25 s on two free cores); "
                "later runs load them"
            )
            progress.info(f"(kept in {kernel_cache_dir()}; 'jeanscv --clear-cache' removes them)")
        records = _unprocessed(found, progress)
        outcomes: dict = {}
        pending = _pending(found.jobs, options, overwrite, progress, outcomes)
        return _run_jobs(pending, options, overwrite, workers, progress, outcomes, records, report, cluster)
    finally:
        if cluster is not None:
            cluster.close()


def _start_workers_early(paths: list[str], jobs: int | None) -> None:
    """Where the arguments may give several inputs and several workers, start the workers'
    fork server before anything else (:func:`pool.start_early`): it loads the library
    and the kernels while this process finds the files."""
    from .discover import may_name_several

    # _workers as for two inputs: whether this run would have several workers for several.
    if may_name_several(paths) and _workers(jobs, 2)[0] > 1:
        from .pool import start_early

        start_early()


def _check_names(ctx: click.Context, values: dict) -> None:
    """``--preset`` and ``--garment`` name something that exists, else a usage error."""
    from jeanscv.errors import JeansError
    from jeanscv.fitting.presets import get_preset
    from jeanscv.plugins import get_garment
    from jeanscv.run.runner import one_line

    for lookup, value, hint in (
        (get_preset, values["preset"], "'--preset'"),
        (get_garment, values["garment"], "'--garment'"),
    ):
        try:
            lookup(value)
        except JeansError as exc:
            raise click.BadParameter(one_line(exc), ctx, param_hint=hint) from None


def _record(status: str, name: str, error: str = "", reason: str | None = None) -> dict:
    """A ``--report`` line of an input that was never processed."""
    record = {"status": status, "input": name, "output": "", "written": [], "error": error, "seconds": 0.0}
    if reason is not None:
        record["reason"] = reason
    return record


def _unprocessed(found, progress) -> list[dict]:
    """Report what the inputs held besides jobs: problems (failed), unsupported files
    and jeanscv's own outputs (skipped)."""
    records = []
    for problem in found.problems:
        progress.error(problem.display, problem.reason)
        progress.counts["failed"] += 1
        records.append(_record("failed", problem.display, error=problem.reason))
    progress.skip_quietly(len(found.ignored))
    records += [_record("skipped", name, reason="not a supported image type") for name in found.ignored]
    for name in found.own_outputs:
        progress.info(f"{name}: skipped (a jeanscv output, not an input)")
        progress.counts["skipped"] += 1
        records.append(_record("skipped", name, reason="a jeanscv output"))
    return records


def _pending(jobs, options, overwrite: bool, progress, outcomes: dict):
    """The jobs to process, taken from discovery as they are needed. A job whose outputs
    all exist (and are newer than the clicks saved beside the photo) is skipped unless
    ``overwrite``, and a clash of outputs fails: both go to ``outcomes`` at once. Before the
    first job bound for an output folder, the temporary files killed runs left there are
    removed (a live run's are locked and kept)."""
    from .discover import Problem
    from .runs import remove_leftovers_in
    from .worker import Outcome, wanted_outputs

    swept: set[Path] = set()
    for index, job in enumerate(jobs):
        if isinstance(job, Problem):
            outcome = Outcome(index, job.display, "failed", error=job.reason)
        elif wanted_outputs(job, options, overwrite):
            for folder in {path.parent for path in job.outputs.values()} - swept:
                remove_leftovers_in(folder)
                swept.add(folder)
            yield job
            continue
        else:
            outcome = Outcome(
                index, job.display, "skipped", str(job.outputs["image"]), error="output exists; --overwrite redoes it"
            )
        outcomes[index] = outcome
        progress.finish(outcome)


def _run_jobs(
    pending, options, overwrite: bool, workers: int, progress, outcomes, records, report, cluster=None
) -> int:
    """Process ``pending`` (on the Dask ``cluster``'s client, else in ``workers`` processes
    when several jobs are pending), summarise, write the ``--report``; the exit status."""
    from .pool import run_parallel
    from .runs import WorkQueue, remove_leftovers

    if report is not None:
        remove_leftovers([report])  # its temporary file, where a run was killed while writing it
    code = 0
    previous = _install_sigterm()
    try:
        queue = WorkQueue(pending, progress, outcomes)
        # Only as many workers as there are files to do: a resumed run with one left runs it here.
        ahead = 0 if cluster is not None else queue.look_ahead(workers)
        if cluster is not None:
            from .cluster import run_on_cluster

            run_on_cluster(queue, options, overwrite, cluster)
        elif workers > 1 and ahead > 1:
            run_parallel(queue, options, overwrite, ahead)
        else:
            _run_serial(queue, options, overwrite)
    except KeyboardInterrupt:
        code = 130
    except _Terminated:
        code = 143
    finally:
        _restore_sigterm(previous)
        if code:
            progress.error("interrupted", "finished outputs are kept; run again to resume")
        records += [outcomes[i].record() for i in sorted(outcomes)]
        progress.summary()
        if report is not None and not _write_report(report, records, progress):
            code = code or 1
    if code:
        return code
    if any(outcome.usage for outcome in outcomes.values()):
        return 2  # an option did not fit its input (a --point outside the image)
    return 1 if progress.counts["failed"] else 0


def _serve_hint(paths) -> str:
    """The ``jeanscv serve`` command that shows a run's photos: its folder when one was
    named, else the first input's folder."""
    import shlex

    first = Path(paths[0])
    folder = first if first.is_dir() else first.parent
    return f"jeanscv serve {shlex.quote(str(folder) + os.sep if str(folder) != '.' else '.')}"


#: Memory one worker may need at its peak (a 24-MP photo; README "Speed").
WORKER_MEMORY_BYTES = 1 << 30


def _available_memory() -> int | None:
    """Bytes of memory available to new processes (Linux), None where unknown."""
    try:
        with open("/proc/meminfo") as info:
            for line in info:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def _workers(jobs: int | None, inputs: int) -> tuple[int, str]:
    """How many worker processes, and why: ``-j`` as given, else one per core for
    several inputs, as far as the available memory holds one worker per GiB."""
    if jobs is not None:
        return jobs, "-j"
    if inputs <= 1:
        return 1, "one input"
    cores = os.cpu_count() or 1
    memory = _available_memory()
    fit = cores if memory is None else max(1, min(cores, memory // WORKER_MEMORY_BYTES))
    if fit < cores:
        return min(fit, inputs), f"{cores} cores, memory for {fit}"
    return min(cores, inputs), f"one per core, {cores} cores"


class _Terminated(BaseException):
    """SIGTERM in the main process: unwinds like Ctrl-C."""


def _raise_terminated(signum, frame) -> None:
    raise _Terminated()


def _install_sigterm():
    try:
        return signal.signal(signal.SIGTERM, _raise_terminated)
    except ValueError:  # not the main thread (embedded use): leave signals alone
        return None


def _restore_sigterm(previous) -> None:
    if previous is not None:
        signal.signal(signal.SIGTERM, previous)


def _run_serial(queue, options, overwrite: bool) -> None:
    from .worker import process, reuse_freed_memory

    reuse_freed_memory()
    while (item := queue.next()) is not None:
        job, wait = item
        queue.progress.start(job.display)
        queue.finish(job, process(job, options, overwrite, wait))


def _write_report(path: Path, records: list[dict], progress) -> bool:
    from jeanscv.errors import JeansError
    from jeanscv.io.write import write_text

    text = "".join(json.dumps(r, sort_keys=True) + "\n" for r in records)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, text)
    except (OSError, JeansError) as exc:
        progress.error(str(path), f"cannot write the report: {exc}")
        return False
    return True


def one_blas_thread() -> None:
    """numpy's OpenBLAS on one thread, unless the environment says otherwise (set before
    numpy loads it, which reads this once; the workers and the fork server inherit it).

    The command's linear algebra is on tiny matrices (the saliency's few-hundred-node
    solve, 3x3 transforms), which a second thread does not speed up; but OpenBLAS's
    threads spin for a while after each call, taking the core that the other ``-j``
    worker, or the segmentation's GrabCut threads, would use: 2.7 to 7 s of CPU more
    for 22 photos with ``-j 2`` (bench.latency's batch).
    """
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def main() -> None:
    """Console-script entry point; ``jeanscv serve ...`` runs the web page's command."""
    from .interrupts import exit_at_once_on_interrupt

    serving = len(sys.argv) > 1 and sys.argv[1] == "serve"
    exit_at_once_on_interrupt(0 if serving else 130)  # already done where _entry started the command
    one_blas_thread()
    if serving:
        from .serve import main as serve_main

        serve_main(sys.argv[2:])
        return
    cli(prog_name="jeanscv")


if __name__ == "__main__":
    sys.exit(main())
