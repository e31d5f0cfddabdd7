"""Command line: ``python -m addon.warp --method NAME|all CONFIG.json`` -> JSON on stdout.

Plain Python and numpy, no bpy. A malformed config prints one line naming the
field and exits with status 2. An empty intersection body is reported in the
output (no maps, ``diagnostics.empty_body`` says why, plus a note on stderr),
not crashed on. An unexpected exception (a bug) is one line on stderr too
(``LIXEL_DEBUG=1`` prints the traceback); with ``--method all`` the other
methods' results are still printed. Output that cannot be written (a full disk) is one line too; a reader that
stops early (``| head``) ends the command quietly, with status 1; Ctrl-C is one line, with status 130.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import traceback

import numpy as np

from ..warp import METHODS, compute, focused_body
from ..warp.types import EmptyBodyError, WarpError
from .config import parse_config
from .output import empty_body_json, name_receivers, setup_json


def _internal(exc: BaseException) -> str:
    """One line for an unexpected exception (a bug): LIXEL_DEBUG=1 shows the traceback."""
    if os.environ.get("LIXEL_DEBUG"):
        traceback.print_exception(exc, file=sys.stderr)
    return f"internal error ({type(exc).__name__}: {exc}); set LIXEL_DEBUG=1 for the traceback"


def _error(message: str, status: int = 2) -> int:
    """The command's one error line on stderr; returns the exit status."""
    print(f"lixel: error: {message}", file=sys.stderr)
    return status


def run_method(name, view, light, scene, options, body):
    if isinstance(body, EmptyBodyError):
        return empty_body_json(name, str(body))
    try:
        setup = compute(name, view, light, scene, options, body=body)
        name_receivers(setup.diagnostics, body, lambda k: f"boxes[{k}]")
        return setup_json(setup)
    except WarpError as exc:
        why = str(exc)
        if isinstance(exc, EmptyBodyError) and name == "cascade" and options.visible_depth_range is not None:
            why += (f" within options.visible_depth_range {list(options.visible_depth_range)}: widen it to the "
                    f"receivers' eye depths or drop the option")
        return {"maps": [], "diagnostics": {"method": name, "error": why, "fallbacks": []}}
    except Exception as exc:  # a bug in one method must not hide the others' results
        return {"maps": [], "diagnostics": {"method": name, "error": _internal(exc), "fallbacks": []}}


class DuplicateKey(Exception):
    """A key given twice in one JSON object."""


def _one_of_each(pairs: list) -> dict:
    """A JSON object's pairs as a dict; :class:`DuplicateKey` where a key comes twice ("far": 70, ..., "far": 7)."""
    seen = {}
    for key, value in pairs:
        if key in seen:
            raise DuplicateKey(repr(key))
        seen[key] = value
    return seen


MAX_INDENT = 16


def _indent(text: str) -> int:
    """``--indent``: spaces per level, 0..MAX_INDENT (json takes a negative one as 0, and a huge one pads every
    line with it)."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_INDENT:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number from 0 to {MAX_INDENT} (spaces per level)")
    return value


def main(argv=None) -> int:
    with np.errstate(all="ignore"):  # numpy's RuntimeWarnings are no message for a user: errors are lines of their own
        try:
            return _main(argv)
        except KeyboardInterrupt:   # Ctrl-C (waiting on a standard input never given, say): a line, no traceback
            print("lixel: interrupted: nothing written", file=sys.stderr)
            return 130


def _main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m addon.warp", description="Lixel light matrices for a config.")
    parser.add_argument("--method", required=True, help=f"one of {', '.join(METHODS)}, or 'all'")
    parser.add_argument("config", help="JSON config file ('-' for standard input)")
    parser.add_argument("--indent", type=_indent, default=None,
                        help=f"pretty-print the JSON with this many spaces per level (0 to {MAX_INDENT})")
    args = parser.parse_args(argv)
    if args.method != "all" and args.method not in METHODS:
        return _error(f"--method: unknown method {args.method!r}; choose one of {', '.join(METHODS)} or all")
    try:
        text = sys.stdin.read() if args.config == "-" else open(args.config, encoding="utf-8").read()
    except OSError as exc:
        return _error(f"config: cannot read {args.config}: {exc.strerror}")
    except UnicodeDecodeError:
        return _error(f"config: {args.config} is not UTF-8 text")
    try:
        # a byte order mark (Windows editors save one) dropped, a key given twice refused
        config = json.loads(text.removeprefix("\ufeff"), object_pairs_hook=_one_of_each)
    except RecursionError:
        return _error("config: nested too deeply")
    except DuplicateKey as exc:
        return _error(f"config: the key {exc} appears twice in one object (JSON keeps the last, silently): keep one")
    except json.JSONDecodeError as exc:
        return _error(f"config: not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})")
    except ValueError as exc:   # an integer longer than Python converts (4300 digits)
        return _error(f"config: not valid JSON ({exc})")
    try:
        view, light, scene, options = parse_config(config)
    except WarpError as exc:
        return _error(str(exc))
    except Exception as exc:
        return _error(f"config: {_internal(exc)}")
    try:
        body = focused_body(view, light, scene, options)     # (as options.focus says: the visible region by default)
    except EmptyBodyError as exc:
        body = exc
        print(f"lixel: note: the intersection body is empty: {exc}", file=sys.stderr)
    except WarpError as exc:
        return _error(str(exc), 1)
    except Exception as exc:
        return _error(f"intersection body: {_internal(exc)}", 1)
    names = list(METHODS) if args.method == "all" else [args.method]
    results = {n: run_method(n, view, light, scene, options, body) for n in names}
    if args.method == "all":
        out = {"methods": results}
    else:
        out = results[args.method]
        if "error" in out["diagnostics"]:
            return _error(f"{args.method}: {out['diagnostics']['error']}", 1)
    try:
        json.dump(out, sys.stdout, indent=args.indent)
        sys.stdout.write("\n")
        sys.stdout.flush()
    except OSError as exc:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())   # nothing left for the flush at exit
        if isinstance(exc, BrokenPipeError):    # the reader stopped early (| head): it has what it wanted
            return 1
        return _error(f"cannot write the output: {exc.strerror or exc}", 1)
    return 0

