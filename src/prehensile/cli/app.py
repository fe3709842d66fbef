"""The typer application, its consoles and the error handling shared by every command module."""

from __future__ import annotations

import functools
import json
import sys

import typer
from rich.console import Console
from rich.markup import escape

from prehensile import kernel_cache
from prehensile.errors import PrehensileError

app = typer.Typer(name="prehensile", help="Robots that reach, grasp and place.", no_args_is_help=True,
                  add_completion=False, pretty_exceptions_enable=False)
bench_app = typer.Typer(help="Benchmarks against peer libraries (JSON + table).", no_args_is_help=True)
app.add_typer(bench_app, name="bench")
console = Console(highlight=False, width=None if sys.stdout.isatty() else 120)
err_console = Console(stderr=True, highlight=False)
COMPILING_COMMANDS = ("fk", "check", "ik", "plan", "demo", "bench")  # they run numba kernels


@app.callback()
def _note_first_compilation(ctx: typer.Context) -> None:
    """Say why the first run of a command is slow: numba compiles the kernels it uses (tens of seconds)."""
    if ctx.invoked_subcommand in COMPILING_COMMANDS and "--help" not in sys.argv and not kernel_cache.cached_kernels():
        err_console.print("[dim]First run: numba compiles the kernels as they are first used, which takes up to a "
                          "minute; later runs load them from its cache.[/dim]")

EXIT_FREE, EXIT_COLLIDING, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3

SRDF_OPTION = typer.Option(None, "--srdf", help="SRDF to apply: planning groups (chains), end effectors, disabled "
                           "collision pairs (default: <stem>.srdf next to a URDF or MJCF file, if present).")
BALL_RADIUS_OPTION = typer.Option(None, "--ball-radius", help="Target radius (m) of the largest balls of the sphere "
                                  "model generated for planning: up to 64 balls per link are tried, and links whose "
                                  "meshes need larger ones keep them, with a warning (default: 8 balls per link mesh, "
                                  "primitives covered to within 2 cm); smaller balls let links pass closer to each "
                                  "other and to obstacles.")


def check_budget(budget: float) -> None:
    """Refuse a ``--budget`` that is not a positive, finite time: an infinite one never ends a
    search for an unreachable goal."""
    if not (budget > 0 and budget < float("inf")):
        raise PrehensileError(f"--budget: must be a positive, finite time (s), got {budget}")


MAX_SEED = 2**32 - 2  # OMPL seeds its generator with seed + 1, a std::uint_fast32_t (32 bits on some platforms)


def check_seed(seed: int) -> None:
    """Refuse a ``--seed`` outside 0 .. :data:`MAX_SEED` (numpy's generators take no negative one)."""
    if not 0 <= seed <= MAX_SEED:
        raise PrehensileError(f"--seed: must be in 0 .. {MAX_SEED}, got {seed}")


def extra_values(args: list[str], given: list[str] | None, option: str, what: str) -> list[str]:
    """All values of the many-valued ``option``: typer binds the first (``given``) and hands the
    rest on as the command's extra ``args``. An extra argument that is an option, not a number,
    is an unknown option; any other that is not a number was meant for the command (its
    positional argument given after the values)."""
    unknown = [a for a in args if a.startswith("-") and not _is_number(a)]
    if unknown:
        raise PrehensileError(f"no such option: {unknown[0]} (see --help)")
    if args and not given:
        raise PrehensileError(f"unexpected arguments {' '.join(args)}; give {what} after {option}")
    words = [a for a in args if not _is_number(a)]
    if words:
        raise PrehensileError(f"{option}: expected numbers, got '{words[0]}'; if it is an argument of the command, "
                              f"give it before {option}, whose values end the command line")
    return list(given or []) + list(args)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def check_ball_radius(ball_radius: float | None) -> None:
    """Refuse a ``--ball-radius`` that is not a positive, finite length."""
    if ball_radius is not None and not 0 < ball_radius < float("inf"):
        raise PrehensileError(f"--ball-radius: must be positive and finite (m), got {ball_radius}")


def handles_errors(command):
    """Turn a PrehensileError into one red line on stderr and exit code 2, and any other
    exception (a bug) into its traceback and exit code 3, so that no failure exits with the
    code of a result (1: colliding, no path, no solution)."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except PrehensileError as err:
            err_console.print(f"[bold red]error:[/] [red]{escape(str(err))}[/]", soft_wrap=True, markup=True)
            raise typer.Exit(EXIT_BAD_INPUT) from None
        except typer.Exit:
            raise
        except Exception:
            err_console.print_exception()
            err_console.print("[bold red]internal error[/] (a bug: please report it with the traceback above)")
            raise typer.Exit(EXIT_INTERNAL) from None

    return wrapper


def echo_json(data) -> None:
    typer.echo(json.dumps(data, indent=2))
