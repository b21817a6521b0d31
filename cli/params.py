"""The callbacks of the command's options: values parsed and checked (a bad one is
click's usage error), or an answer printed before the command exits (``--list-presets``).
Imports click alone at module level (``--help`` stays fast)."""

from __future__ import annotations

import click


def rect_as_box(ctx: click.Context, param: click.Parameter, value: str | None):
    """``--rect X,Y,W,H``, the old name of ``--box X0,Y0,X1,Y1``: the box, and one line
    on stderr saying so (the library's ``rect`` option is GrabCut's and stays)."""
    if value is None:
        return None
    try:
        x, y, w, h = (int(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter("expected four integers X,Y,W,H, e.g. 10,20,300,200") from None
    if w <= 0 or h <= 0:
        raise click.BadParameter("width and height must be positive")
    box = f"{x},{y},{x + w},{y + h}"
    click.echo(f"jeanscv: --rect X,Y,W,H is now --box X0,Y0,X1,Y1 (here --box {box})", err=True)
    return parse_box(ctx, param, box)


def parse_points(ctx: click.Context, param: click.Parameter, values: tuple[str, ...]):
    points = []
    for value in values:
        try:
            x, y = (float(v) for v in value.split(","))
        except ValueError:
            raise click.BadParameter(f"expected two numbers X,Y (image pixels), e.g. 420,310; got {value!r}") from None
        if not (abs(x) < float("inf") and abs(y) < float("inf")):
            raise click.BadParameter(f"expected finite numbers X,Y, got {value!r}")
        points.append((x, y))
    return tuple(points)


def parse_box(ctx: click.Context, param: click.Parameter, value: str | None):
    if value is None:
        return None
    try:
        x0, y0, x1, y1 = (float(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(
            f"expected four numbers X0,Y0,X1,Y1 (image pixels), e.g. 100,50,620,480; got {value!r}"
        ) from None
    if not all(abs(v) < float("inf") for v in (x0, y0, x1, y1)):
        raise click.BadParameter(f"expected finite numbers, got {value!r}")
    if x1 - x0 < 2 or y1 - y0 < 2:
        raise click.BadParameter("the box needs X0 < X1 and Y0 < Y1, at least 2 pixels apart")
    return x0, y0, x1, y1


def list_presets(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    from jeanscv.fitting.presets import DEFAULT_PRESET, PRESETS

    for name, preset in PRESETS.items():
        mark = " (default)" if name == DEFAULT_PRESET else ""
        click.echo(f"{name}{mark}: {preset.description}")
    ctx.exit(0)


def clear_cache(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    from jeanscv.fitting._fast.cache import clear_kernel_cache

    try:
        folder, files, size = clear_kernel_cache()
    except OSError as exc:
        click.echo(f"jeanscv: cannot remove the compiled kernels: {exc.strerror or exc}", err=True)
        ctx.exit(1)
    if files:
        click.echo(f"removed the compiled fit kernels: {files} files, {size / 1e6:.1f} MB, from {folder}")
    else:
        click.echo(f"no compiled fit kernels to remove ({folder})")
    ctx.exit(0)


def check_silhouette(ctx: click.Context, param: click.Parameter, value: str) -> str:
    from jeanscv.plugins import available_silhouette_methods

    known = available_silhouette_methods()
    if value not in known:
        raise click.BadParameter(f"{value!r} is not one of {', '.join(sorted(known))}")
    return value


def list_garments(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    from jeanscv.plugins import available_garments

    for name, garment in available_garments().items():
        click.echo(f"{name}: {garment.description}")
    ctx.exit(0)
