"""The ``fisheye-des`` command line (typer).

Each sub-command lives in ``pipeline/commands/<name>.py`` and defines ``register(app)``; add its
name to ``COMMANDS`` below. Commands import heavy modules (cv2, matplotlib, torch) inside their
functions so that ``fisheye-des --help`` stays fast.

Errors: library code raises ``estimators.errors.FisheyeDesError``; here it becomes one line on
stderr and exit code 2 (no traceback unless ``--debug``). Ctrl-C exits with 130 after the command's
own clean-up has run; so does a SIGTERM (a supervisor's stop: systemd, a launch file, ``docker
stop``), which the command takes as a Ctrl-C. Anything else (a bug), and any error under
``--debug``, is raised on: Python prints its traceback and exits with 1.
"""

from __future__ import annotations

import importlib
import inspect
import signal
import sys
import threading

import typer

from estimators.errors import FisheyeDesError

COMMANDS: tuple[str, ...] = (
    "demo", "run", "live", "simulate", "evaluate", "accuracy", "bench", "calibrate", "thesis",
)

app = typer.Typer(
    name="fisheye-des",
    help="Obstacle ranges for drones from raw fisheye cameras (monocular parallax, stereo, fusion).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

_state = {"debug": False}


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show full tracebacks on errors.")) -> None:
    _state["debug"] = debug


for _name in COMMANDS:
    importlib.import_module(f"pipeline.commands.{_name}").register(app)
# --help shows a command's docstring; typer keeps the single line breaks of its later paragraphs, which
# wrapped at the source's width break the terminal's lines mid-sentence: one line per paragraph instead
for _info in app.registered_commands:
    _doc = _info.help or inspect.getdoc(_info.callback) or ""
    _info.help = "\n\n".join(" ".join(par.split()) for par in _doc.split("\n\n"))


INTERRUPTED = 130
_GENERIC_NOTE = "fisheye-des: interrupted; outputs written so far are kept"


def interrupted(note: str) -> typer.Exit:
    """A command's own note on a Ctrl-C (where its outputs are), printed instead of :func:`main`'s
    generic one; the command raises the returned Exit (code 130)."""
    print(note, file=sys.stderr)
    _state["noted"] = True
    return typer.Exit(INTERRUPTED)


def _sigterm_as_ctrl_c(signum, frame) -> None:
    raise KeyboardInterrupt  # the command's own Ctrl-C clean-up: summary.json written, exit 130


def main(argv: list[str] | None = None) -> int:
    """Console-script entry point; returns the process exit code."""
    args = sys.argv[1:] if argv is None else argv
    _state["noted"] = False
    # (a handler can be set from the main thread only; it is put back on return)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _sigterm_as_ctrl_c) if main_thread else None
    try:
        return _main(args)
    finally:
        if main_thread:  # (None: a handler not set from Python, i.e. the default)
            signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def _main(args: list[str]) -> int:
    try:
        rc = app(args=args, standalone_mode=False)
    except FisheyeDesError as e:
        if _state["debug"] or "--debug" in args:
            raise
        print(f"fisheye-des: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        rc = INTERRUPTED
    except SystemExit as e:  # typer/click exits (e.g. --help)
        return int(e.code or 0)
    except Exception as e:  # click usage errors and the like
        import click

        # typer >= 0.2x raises its own vendored click's exceptions (typer._click), which are not
        # click's classes: recognise a usage error by its interface (show() and an int exit_code).
        if isinstance(e, click.exceptions.ClickException) or (
            callable(getattr(e, "show", None)) and isinstance(getattr(e, "exit_code", None), int)
        ):
            e.show()
            return e.exit_code
        if not isinstance(e, click.exceptions.Abort | typer.Abort):
            raise
        rc = INTERRUPTED  # (click's form of a Ctrl-C)
    # typer turns a Ctrl-C (KeyboardInterrupt) in a command into exit code 130 itself, silently: the
    # generic note unless the command gave its own (``interrupted``)
    if rc == INTERRUPTED and not _state["noted"]:
        print(_GENERIC_NOTE, file=sys.stderr)
    return rc if isinstance(rc, int) else 0


if __name__ == "__main__":  # python -m pipeline.cli: run the package's module, whose state (``_state``)
    from pipeline.cli import main as package_main  # the commands share, not this __main__ copy's

    sys.exit(package_main())
