"""What every command line of the package shares: the help formatter, the parser with its one
error style, the argument types, the tqdm progress bar, and the one-line failure printer.

Standard library only (tqdm is imported when a bar is made), so that any command's parser can
be built, and its ``--help`` printed, before its optional extra is installed.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from ._extras import MissingExtra, as_missing_extra
from .errors import RustclothError

if TYPE_CHECKING:
    from tqdm import tqdm

#: What a user's input can make the package raise: a bad scene or value, an unreadable or
#: unwritable file, a file nested too deeply to read. Each is reported in one line, exit 2;
#: anything else is a bug and keeps its traceback.
USER_ERRORS: tuple[type[BaseException], ...] = (
    RustclothError, ValueError, TypeError, OSError, RecursionError)


class Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Each option's default after its help, unless there is none to show (None, a flag's
    False) or the help already says it; descriptions keep their line breaks."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if action.default is None or action.default is False or "(default:" in text:
            return action.help
        return super()._get_help_string(action)


class Parser(argparse.ArgumentParser):
    """Errors in one line, ``PROG: error: what (see PROG --help)``, exit status 2."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", Formatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


def positive(text: str) -> float:
    """A positive, finite number (argparse names the option in front of the message)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, not {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive, finite number, not {text!r}")
    return value


def positive_int(text: str) -> int:
    """A whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, not {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, not {text!r}")
    return value


def one_line(message: object) -> str:
    """The first line of a message (a scene error may carry the offending TOML below it)."""
    lines = str(message).strip().splitlines()
    return lines[0] if lines else type(message).__name__


def describe(err: BaseException) -> str:
    """A user's error as one line: an OSError as its reason and file, not ``[Errno 20] ...``."""
    if isinstance(err, RecursionError):
        return "the input is nested too deeply to read"
    if isinstance(err, OSError) and err.strerror:
        names = [n for n in (err.filename, err.filename2) if n is not None]
        return f"{err.strerror}: {' -> '.join(repr(str(n)) for n in names)}" if names \
            else err.strerror
    return one_line(err)


def fail(prog: str, message: str) -> int:
    """Print ``PROG: error: MESSAGE`` on one line to stderr; returns the exit status, 2."""
    print(f"{prog}: error: {one_line(message)}", file=sys.stderr)
    return 2


def guarded(prog: str, command: Callable[[], int]) -> int:
    """Run ``command`` and return its exit status, with what goes wrong said in one line:
    argparse's own exits (help, errors) pass through as their status, a missing extra and a
    user's error (:data:`USER_ERRORS`) exit 2, an interrupt 130."""
    try:
        return command()
    except SystemExit as stop:
        return stop.code if isinstance(stop.code, int) else 0 if stop.code is None else 1
    except MissingExtra as err:
        return fail(prog, str(err))
    except ModuleNotFoundError as err:
        missing = as_missing_extra(err, prog)
        if missing is None:
            raise
        return fail(prog, str(missing))
    except USER_ERRORS as err:
        return fail(prog, describe(err))
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130


def writable_folder(folder: Path) -> None:
    """Create ``folder`` if missing and check that it takes files, so that a command fails at
    its start, not after its work: a file in the way or /dev/full raise here, as does a folder
    that takes no files (/proc, a read-only mount)."""
    folder.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:  # named after the folder, not the probe's temporary name
        raise OSError(err.errno, f"cannot write files in this folder ({err.strerror})",
                      str(folder)) from None


def progress(total: int, unit: str, initial: int = 0) -> tqdm[Any]:
    """The package's progress bar: tqdm on stderr, drawn on a terminal only and cleared when
    it closes, so that stdout keeps only results."""
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit=unit, disable=None, leave=False,
                file=sys.stderr, dynamic_ncols=True)
