"""The ``snapshot`` command: a thin shell over the packages.

Subcommands are registered as entry points (group ``action_snapshot.commands`` in
``pyproject.toml``) and imported only when used, so ``snapshot info`` does not pay for
Streamlit or matplotlib, and snapcore never imports study_app or analysis.

Errors: every :class:`~snapcore.errors.SnapshotError` (bad BVH, bad manifest, bad
database URL...) and every ``OSError`` becomes one line on stderr, ``error: <file>:<line>:
<what>``, with exit code 2 and no traceback. So does every click usage error (a bad
option value, an unknown option or command, a missing argument, a ``click.BadParameter``
raised by a command): ``error: <click's message>`` instead of click's four-line usage
block. ``snapshot`` with no arguments still prints the help; ``--help`` and ``--version``
are click's. Warnings become one ``warning:`` line each. ``SNAPSHOT_DEBUG=1`` shows the
traceback for developers.
"""

from __future__ import annotations

import os
import sys
import warnings
from importlib.metadata import entry_points

import click

from snapcore.errors import SnapshotError

__all__ = ["main", "cli", "EXIT_BAD_INPUT"]

#: Exit status for bad input or a failed request (click uses 2 for usage errors too).
EXIT_BAD_INPUT = 2
ENTRY_POINT_GROUP = "action_snapshot.commands"


class _OneLineError(click.ClickException):
    """A click error (bad option value, unknown option or command, missing argument...)
    shown as one ``error: <click's message>`` line instead of click's usage block.
    Exit code 1, click's own for an error a command raises."""

    def __init__(self, err: click.ClickException):
        text = " ".join(ln.strip() for ln in err.format_message().splitlines() if ln.strip())
        super().__init__(text)

    def show(self, file=None):
        click.echo(f"error: {self.format_message()}", file=file, err=True)


class _OneLineBadInput(_OneLineError):
    """A usage or file error as one line, exit code 2 (click's ``exit_code`` is a class
    variable, hence a class per code)."""

    exit_code = EXIT_BAD_INPUT


def _one_line(err: click.ClickException) -> click.ClickException:
    """``err`` as a one-line error; ``snapshot`` alone (help for no arguments) stays as is."""
    if isinstance(err, (click.exceptions.NoArgsIsHelpError, _OneLineError)):
        return err
    if isinstance(err, (click.UsageError, click.FileError)):
        return _OneLineBadInput(err)
    return _OneLineError(err)


def _commands() -> dict:
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


class _LazyGroup(click.Group):
    """A click group whose subcommands are entry points loaded on first use."""

    def list_commands(self, ctx):
        return sorted(_commands())

    def get_command(self, ctx, name):
        ep = _commands().get(name)
        if ep is None:
            return None
        try:
            return ep.load()
        except (ImportError, AttributeError) as err:
            # A command whose module is broken or whose optional part is not installed:
            # say so in one line instead of failing every other command.
            reason = str(err)

            @click.command(name=name, help=f"(unavailable: {reason})")
            def unavailable():
                raise click.ClickException(f"command '{name}' is unavailable: {reason}")

            return unavailable

    def parse_args(self, ctx, args):
        # errors in the group's own options (`snapshot --bogus`)
        try:
            return super().parse_args(ctx, args)
        except click.ClickException as err:
            raise _one_line(err) from None

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except click.ClickException as err:
            # an unknown command, a subcommand's bad option or missing argument, a
            # click.BadParameter raised by a command: one line, exit code 2
            raise _one_line(err) from None
        except SnapshotError as err:
            if os.environ.get("SNAPSHOT_DEBUG"):
                raise
            click.echo(f"error: {err}", err=True)
            ctx.exit(EXIT_BAD_INPUT)
        except OSError as err:
            if os.environ.get("SNAPSHOT_DEBUG"):
                raise
            where = f"{err.filename}: " if getattr(err, "filename", None) else ""
            click.echo(f"error: {where}{err.strerror or err}", err=True)
            ctx.exit(EXIT_BAD_INPUT)


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    # through tqdm, so a warning raised under a progress bar gets a line of its own and
    # the bar is redrawn below it (a plain write would splice it into the bar)
    from tqdm import tqdm

    tqdm.write(f"warning: {message}", file=sys.stderr)
    sys.stderr.flush()  # in order with what the command prints next


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="action-snapshot", prog_name="snapshot")
def cli():
    """Action Snapshot: one still image that tells the story of a character animation.

    Reads motion capture (BVH, one or two characters, or a scene manifest), picks the
    most informative pose (story information; the paper's pose entropy with
    --pose-method paper) and view (Projected Motion Area), renders
    stills, videos and bas-reliefs, runs the user study and analyses it.

    Run `snapshot COMMAND --help` for each command. Real motion data is found through
    SNAPSHOT_DATA (default ../shared/motions).
    """
    if not os.environ.get("SNAPSHOT_DEBUG"):
        warnings.showwarning = _one_line_warning
    from snapcore._memory import tune_allocator

    tune_allocator()  # reuse freed NumPy temporaries instead of page-faulting fresh ones


def main(argv=None) -> int:
    """Console-script entry point."""
    try:
        cli.main(args=argv, prog_name="snapshot", standalone_mode=True)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
