"""``jeanscv --help`` in sections, as a reader looks for the options: what goes in and
out first, then what to dress, the garment, memes, clips, limits and speed.

Click has no option groups: :class:`SectionedCommand` writes its options under the
titles of :data:`SECTIONS`. Imports click alone (``--help`` stays fast).
"""

from __future__ import annotations

import click

#: Section title -> the options in it, by their long name, in the order shown. Every
#: option that ``--help`` shows is in exactly one (``tests/test_cli.py`` checks).
SECTIONS: dict[str, tuple[str, ...]] = {
    "Inputs and outputs": (
        "--output-dir",
        "--recursive",
        "--format",
        "--overwrite",
        "--json",
        "--svg",
        "--gif",
        "--gif-frames",
        "--report",
        "--quiet",
        "--verbose",
    ),
    "What to dress": (
        "--subject",
        "--detector",
        "--objects",
        "--point",
        "--background-point",
        "--box",
        "--clicks",
        "--mask",
        "--kind",
        "--silhouette",
        "--threshold",
    ),
    "The jeans": (
        "--style",
        "--clip",
        "--garment",
        "--posture",
        "--preset",
        "--iterations",
        "--seed",
        "--starts",
    ),
    "Memes": ("--top", "--bottom", "--side-by-side"),
    "Clips": ("--max-frames",),
    "Limits and speed": (
        "--jobs",
        "--dask",
        "--max-pixels",
        "--raw-half-size",
        "--device",
        "--backend",
    ),
    "Information": ("--list-presets", "--list-garments", "--clear-cache", "--version", "--help"),
}

#: A line under a section's title, before its options.
NOTES = {
    "Clips": "GIF, MP4, MOV, WebM, MKV, animated WebP and PNG: the jeans follow the subject frame by "
    "frame. --format gif, mp4 or webp converts them.",
}


def option_name(param: click.Parameter) -> str:
    """The name an option is listed by in :data:`SECTIONS`: its first long form."""
    return next((opt for opt in param.opts if opt.startswith("--")), param.opts[0])


class SectionedCommand(click.Command):
    """A command whose ``--help`` lists its options in :data:`SECTIONS`, one column
    width for all of them; an option in no section would follow under "Options"."""

    def format_options(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        records = {}
        for param in self.get_params(ctx):
            record = param.get_help_record(ctx) if isinstance(param, click.Option) else None
            if record is not None:
                records[option_name(param)] = record
        groups = [
            (title, [records.pop(name) for name in names if name in records]) for title, names in SECTIONS.items()
        ]
        groups.append(("Options", list(records.values())))
        # Pad the first column to one width (click's widest, 30), so the help texts of
        # every section start in the same column.
        width = min(30, max((len(term) for _, rows in groups for term, _ in rows), default=0))
        for title, rows in groups:
            if rows:
                with formatter.section(title):
                    if title in NOTES:
                        formatter.write_text(NOTES[title])
                    formatter.write_dl([(term.ljust(width), text) for term, text in rows])
