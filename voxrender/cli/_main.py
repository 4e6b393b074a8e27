"""The ``voxrender`` command group and how every command reports: progress on a terminal, warnings as one line,
and errors as one line naming the flag at fault (bad input, exit 2) or saying it is a bug (exit 1).
"""

from __future__ import annotations

import os
import sys
import time
import warnings

import click

from .. import __version__
from ..errors import InputError
from ..outputs.output_kinds import OUTPUTS


def progress(iterable, length=None, label=None):
    """A click progress bar on stderr when it is a terminal; the bare iterable otherwise.  Items that are byte
    counts (a streamed encode's slabs) show as MB read, MB/s and the time left.
    """
    if not sys.stderr.isatty():
        return iterable
    stream = sys.modules.get("voxrender.object.stream")          # imported by the commands that stream, and only then
    if stream and isinstance(iterable, stream.ByteCounts):
        return _byte_bar(iterable, length, label)
    return _bar(iterable, length, label)


def _byte_bar(counts, length, label):
    started, done = time.perf_counter(), 0

    def rate(_):
        seconds = max(time.perf_counter() - started, 1e-6)
        return f"{done / 1e6:,.0f} of {length / 1e6:,.0f} MB, {done / 1e6 / seconds:,.0f} MB/s"

    with click.progressbar(length=length, label=label, file=sys.stderr, item_show_func=rate, show_eta=True,
                           show_percent=True) as bar:
        for count in counts:
            yield count
            done += count
            bar.update(count, count)


def _bar(iterable, length, label):
    with click.progressbar(iterable, length=length, label=label, file=sys.stderr) as bar:
        yield from bar


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    """A warning as one line, each once a command: a file read twice (``info`` reads it, then opens it as a stream)
    says what it says once.
    """
    if str(message) not in _WARNED:
        _WARNED.add(str(message))
        click.echo(f"warning: {message}", err=True)


_WARNED = set()


# Library parameters whose flag is not "--" + the name with dashes; the outputs' flags are in their records.
FLAGS = {"picture": "--pattern", "inputs": "INPUT", "compare": "--compare-rays", "views": "the manifest's views",
         "planes": "--slices",
         **{name: f"--{kind.flag}" for name, kind in OUTPUTS.items() if kind.flag}}


def _placed(error, args):
    """The error's line: led by the flag at fault when the user gave that flag; when not, the flag that is the
    fix follows the message (a 4-D file asks for ``--frame``), so that no line blames a flag nobody gave.

    >>> _placed(InputError("choose a frame", parameter="frame"), ["in.nii"])
    'choose a frame (--frame)'
    >>> _placed(InputError("must be positive", parameter="scale"), ["in.nii", "--scale=-1"])
    '--scale: must be positive'
    """
    if not error.parameter:
        return error.message
    name = flag(error.parameter)
    if not name.startswith("-") or any(arg == name or arg.startswith(name + "=") for arg in args):
        return f"{name}: {error.message}"
    return f"{error.message} ({name})"


def flag(parameter):
    """The command-line flag of a library parameter.

    >>> flag("cut_depth"), flag("depth")
    ('--cut-depth', '--depth-out')
    """
    return FLAGS.get(parameter, "--" + parameter.replace("_", "-"))


# ---------------------------------------------------------------- commands

class _Group(click.Group):
    def main(self, args=None, prog_name=None, **extra):
        warnings.showwarning = _one_line_warning
        _WARNED.clear()
        try:
            return super().main(args, prog_name, standalone_mode=False, **extra)
        except click.exceptions.Exit as done:
            sys.exit(done.exit_code)
        except click.exceptions.Abort:
            click.echo("aborted", err=True)
            sys.exit(130)
        except click.ClickException as exc:
            hint = f" (see '{exc.ctx.command_path} --help')" if getattr(exc, "ctx", None) else ""
            click.echo(f"error: {exc.format_message()}{hint}", err=True)
            sys.exit(2)
        except InputError as exc:
            click.echo(f"error: {_placed(exc, sys.argv[1:] if args is None else args)}", err=True)
            sys.exit(2)
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            sys.exit(130)
        except MemoryError:  # sizes are checked before allocating, so running out is not the input's fault
            click.echo("internal error: out of memory; --crop a subregion or choose a larger --voxel", err=True)
            sys.exit(1)
        except Exception as exc:  # a bug: one line unless debugging
            if os.environ.get("VOXRENDER_DEBUG"):
                raise
            click.echo(f"internal error: {type(exc).__name__}: {exc} (VOXRENDER_DEBUG=1 shows the traceback)",
                       err=True)
            sys.exit(1)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="voxrender")
def main():
    """Shaded pictures of the object inside a stack of CT-like slices."""
