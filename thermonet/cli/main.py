"""Entry point of the ``thermonet`` command.

Subcommands: ``run [SCENE]`` (run a scene, write ParaView output), ``info MESH|SCENE`` (what a
mesh or scene holds, memory, stable step), ``render OUTDIR`` (a picture of a frame, needs
PyVista), ``study`` (convergence and cost studies), ``plot OUTDIR`` (PNGs of the diagnostics,
loads and probes). ``--debug`` shows a traceback instead of the one-line error.

Exit codes: 0 success; 1 unexpected thermonet error; 2 bad input (scene, mesh, parameters,
names, checkpoint, an output folder of a previous run, missing optional dependency); 3 the
simulation had to stop (non-physical state, solver failure, a step above the stability limit,
energy far from its start) or ended with broken conservation; 4 output that could not be written
(read-only folder, full disk); 130 interrupted (Ctrl-C; a run can continue with ``--resume``).
"""

from __future__ import annotations

import argparse
import sys

from . import info as info_cmd, plot as plot_cmd, render as render_cmd, run as run_cmd, study as study_cmd
from ..errors import ThermonetError
from ..io.folder import describe_os_error

SUBCOMMANDS = {"run": run_cmd, "info": info_cmd, "render": render_cmd, "study": study_cmd, "plot": plot_cmd}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="thermonet",
        description="Structure-preserving simulation of thermo-elastic spring nets (Mata & Lew 2011).",
    )
    parser.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show a traceback on errors")
        module.add_args(p)
        p.set_defaults(handler=module.handle)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # the command line as given (run.log)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return int(args.handler(args) or 0)
    except ThermonetError as exc:
        if args.debug:
            raise
        if not getattr(args, "echo", False):  # (an MPI process beside rank 0: the same error, said once)
            print(f"thermonet: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:  # a file an output writer could not write, outside `thermonet run`'s own handling
        if args.debug:
            raise
        print(f"thermonet: error: {describe_os_error(exc)}", file=sys.stderr)
        return 4
    except KeyboardInterrupt:
        if not getattr(args, "echo", False):
            print("thermonet: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
