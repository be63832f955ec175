"""The ``wearbench`` command line: one entry point, one module per subcommand in this package.

Each subcommand module defines ``register(subparsers)`` which adds its parser and sets
``func(args) -> int``. Modules are imported by name, and ``wearbench COMMAND`` imports its own module
only (``build_parser(command)``), so a command starts without every other command's imports.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import re
import signal
import sys
import threading
from importlib.metadata import version
from types import FrameType

__all__ = ["COMMANDS", "main"]

# subcommand -> module in wearbench.cli
COMMANDS: dict[str, str] = {
    "bench": "bench",
    "simulate": "simulate",
    "wear": "wear",
    "study": "study",
    "sweep": "sweep",
    "record": "record",
    "taptest": "taptest",
    "inspect": "inspect",
    "recover": "recover",
    "emulate": "emulate",
    "compare": "compare",
    "identify": "identify",
    "calibrate": "calibrate",
    "estimate": "estimate",
    "estimator": "estimator",
    "track": "track",
    "ensemble": "ensemble",
    "demo": "demo",
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The program's parser: every command's (``wearbench --help``, the reference), or with ``command``
    only that one's, so a command imports its own module and not every other command's (the demo's
    truths, the model's compiler: about a second and a half of CPU at each start)."""
    parser = argparse.ArgumentParser(
        prog="wearbench",
        description="Mechanism test beds with worn revolute clearance joints: record bench sessions to "
        "MCAP, simulate the multibody theory, and score measurement against theory.",
        epilog="Quantities take units: 0.6mm, -5pi (rad/s), 300rpm, 1Hz. Run 'wearbench demo' for the "
        "whole toolkit on the built-in simulated bench; 'wearbench COMMAND --help' for each command.",
    )
    parser.add_argument("--version", action="version", version=f"wearbench {version('wearbench')}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMANDS.values() if command is None else (COMMANDS[command],):
        importlib.import_module(f"wearbench.cli.{module}").register(sub)
    _allow_negative_values(parser)
    return parser


def _allow_negative_values(parser: argparse.ArgumentParser) -> None:
    """Let option values that look like negative quantities through as values (``--speed -2pi``,
    ``--t-end -1s``): argparse takes only plain negative numbers as values. No wearbench option
    looks like a negative number, so nothing is lost."""
    parser._negative_number_matcher = re.compile(r"^-(\d|\.\d|pi|π)")
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _allow_negative_values(child)


INTERRUPT_GRACE = 0.5  # s: after Ctrl-C, time for the command to unwind before the process ends regardless


class _Interrupt:
    """Ctrl-C for the program: the first SIGINT raises KeyboardInterrupt (so a recording finishes its
    file) and starts a watchdog that ends the process with exit 130 after INTERRUPT_GRACE if the
    command has not unwound by then (an interrupt swallowed by a library callback, a slow shutdown)."""

    command = "wearbench"
    reported = False
    timer: threading.Timer | None = None

    @classmethod
    def handler(cls, signum: int, frame: FrameType | None) -> None:
        if cls.timer is None:
            cls.timer = threading.Timer(INTERRUPT_GRACE, cls.force_exit)
            cls.timer.daemon = True
            cls.timer.start()
        while frame is not None:  # not inside numba or LLVM (callbacks from C): an exception there is
            name = frame.f_code.co_filename  # lost or can crash the process; the watchdog ends it
            if "/numba/" in name or "/llvmlite/" in name:
                return
            frame = frame.f_back
        raise KeyboardInterrupt

    @staticmethod
    def unraisable(info: object) -> None:
        """sys.unraisablehook: a Ctrl-C that lands in a callback from C (numba's LLVM object cache) is
        not a traceback for the user; the watchdog ends the process."""
        if not isinstance(getattr(info, "exc_value", None), KeyboardInterrupt):
            sys.__unraisablehook__(info)

    @classmethod
    def report(cls) -> None:
        if not cls.reported:
            cls.reported = True
            print(f"{cls.command}: interrupted", file=sys.stderr)

    @classmethod
    def force_exit(cls) -> None:
        cls.report()
        _release_process_resources()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(130)


def main(argv: list[str] | None = None) -> int:
    """Run the command line (``argv`` default: sys.argv). As the program itself (no ``argv``, main
    thread) Ctrl-C ends any command within about a second with one line and exit 130."""
    as_program = argv is None and threading.current_thread() is threading.main_thread()
    if as_program:
        signal.signal(signal.SIGINT, _Interrupt.handler)
        sys.unraisablehook = _Interrupt.unraisable
    # named before parsing, so a Ctrl-C while a slow start imports still says which command it stopped
    named = next((w for w in (sys.argv[1:] if argv is None else argv) if not w.startswith("-")), None)
    command = _Interrupt.command = f"wearbench {named}" if named in COMMANDS else "wearbench"
    try:
        parser = build_parser(named if named in COMMANDS else None)
        args = parser.parse_args(argv)
        command = _Interrupt.command = f"wearbench {args.command}"
        from wearbench.cli.progress import compile_note_on
        from wearbench.compute.threads import one_blas_thread

        # any command may run the model: its first compile says so, whichever; its linear algebra runs
        # on one BLAS thread, as a Dask worker's does
        with compile_note_on(), one_blas_thread():
            return int(args.func(args) or 0)
    except BaseException as exc:
        # Ctrl-C: one line, exit 130 (a recording has finished its file by now). Also whatever error ends
        # the command after the program heard one: a library can turn the KeyboardInterrupt into an error
        # of its own and drop it (pybind11's argument conversion in matplotlib's savefig raised TypeError)
        if _interrupted(exc) or (as_program and _Interrupt.timer is not None):
            if as_program:  # end here, as the watchdog does: nothing in the interpreter's shutdown can
                # change the exit code (seen once in CI: the line printed, then death by SIGINT, -2)
                _Interrupt.force_exit()
            else:
                print(f"{command}: interrupted", file=sys.stderr)
            return 130
        if isinstance(exc, BrokenPipeError):  # the reader left (`wearbench inspect s.mcap | head`): end quietly
            _silence_stdout()
            return 0
        if isinstance(exc, (ValueError, OSError, RuntimeError)):  # errors meant for the user: one clear line
            print(f"{command}: error: {exc}", file=sys.stderr)
            return 2
        raise
    finally:
        if as_program:  # the command is done: a Ctrl-C while the interpreter shuts down changes nothing
            signal.signal(signal.SIGINT, signal.SIG_IGN)


def _release_process_resources() -> None:
    """Before ``os._exit``, which skips multiprocessing's exit clean-up and every ``finally``: kill the
    processes the command started that still run (a local cluster's workers, an emulator, a child
    still being spawned; ``wearbench.compute.interrupts``, loaded by whatever started them), remove
    the outputs it was still writing (their temporary names; the old outputs stay), then run
    multiprocessing's exit finalizers (priority >= 0: they unlink the named semaphores of a local
    cluster's process handles) and release what another thread was still closing
    (``interrupts.release_resources``), so its resource tracker has nothing left to warn about
    ("leaked semaphore objects")."""
    interrupts = sys.modules.get("wearbench.compute.interrupts")  # never imported here: main may hold
    if interrupts is not None:  # the import lock when the watchdog runs
        with contextlib.suppress(Exception):  # best effort on the way out
            interrupts.end_processes()
        with contextlib.suppress(Exception):  # also a child whose start another thread had not finished
            interrupts.end_children()
    outputs = sys.modules.get("wearbench.bench.output_file")  # outputs being written: nothing half-done stays
    if outputs is not None:
        with contextlib.suppress(Exception):
            outputs.remove_unfinished()
    util = sys.modules.get("multiprocessing.util")
    if util is not None:
        with contextlib.suppress(Exception):  # best effort on the way out
            util._run_finalizers(0)
    if interrupts is not None:  # what another thread was closing when the Ctrl-C came
        with contextlib.suppress(Exception):
            interrupts.release_resources()


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so nothing flushed at exit meets the closed pipe again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass


def _interrupted(exc: BaseException) -> bool:
    """True if ``exc`` is a KeyboardInterrupt or was raised while handling one: a Ctrl-C landing in a
    numba dispatcher surfaces as ``SystemError: CPUDispatcher(...) returned a result with an exception
    set``, caused by the KeyboardInterrupt."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


if __name__ == "__main__":
    sys.exit(main())
