"""The contract every study keeps (Study) and the one loop that runs any of them.

A study is a module of bench/ with a module-level STUDY: its own flags, a run that returns a
result (a dict of numbers, lists and strings: JSON once non-finite floats are None), a report
that prints the result for a person, and the Markdown block it writes into a document between
`<!-- NAME:begin ... -->` and `<!-- NAME:end -->` (its own, or by default the command that ran
and its report, preformatted). `pingpong bench NAME` and `python -m bench.MODULE` both go
through run(): flags parsed, study run, result printed as JSON (--json) or reported, the block
rewritten (--readme FILE).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bench import STUDIES

Progress = Callable[[str], None]


def _no_arguments(parser: argparse.ArgumentParser) -> None:
    """A study without flags of its own."""


@dataclass(frozen=True)
class Study:
    """One study of `pingpong bench`.

    run(args, progress): the result, from the parsed flags (args.quick and args.json are always
    there); progress(message) tells a person what it is doing, None under --json. Bad input
    raises ValueError with a message that names the flag and how to fix it.
    report(result): prints the result for a person.
    add_arguments(parser): the study's own flags.
    block: (NAME, text(result, document)): the Markdown block --readme FILE rewrites, document
    being FILE's path (for links relative to it); None: the block named as the study is, holding
    the command and its report.
    quick: what --quick does, for --help (None: the study has no --quick).
    """

    run: Callable[[argparse.Namespace, Progress | None], dict]
    report: Callable[[dict], None]
    add_arguments: Callable[[argparse.ArgumentParser], None] = _no_arguments
    block: tuple[str, Callable[[dict, Path], str]] | None = None
    quick: str | None = "fewer cases and repeats (smoke runs)"


def quick_only(study_function: Callable[..., dict]) -> Callable[[argparse.Namespace, Progress | None], dict]:
    """The run of a study whose only flag is --quick: study_function(quick=..., progress=...)."""
    def run_quick(args: argparse.Namespace, progress: Progress | None) -> dict:
        return study_function(quick=args.quick, progress=progress)

    return run_quick


def to_json(value):
    """value with every non-finite float replaced by None and numpy scalars by Python's (JSON has
    no infinity: a missed impact)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    if hasattr(value, "item"):  # numpy scalars
        return to_json(value.item())
    return value


def write_block(path: str | Path, name: str, text: str) -> None:
    """Replace the text between the NAME markers of a Markdown file, and nothing else; the begin
    marker's note (`<!-- NAME:begin (note) -->`) stays."""
    path = Path(path)
    content = path.read_text()
    begin, end = f"<!-- {name}:begin", f"<!-- {name}:end -->"
    if begin not in content or end not in content:
        raise ValueError(f"{path}: no `{begin} ... -->` ... `{end}` markers; add them where the block goes")
    start = content.index(begin)
    head_end = content.index("-->", start) + 3
    stop = content.index(end, head_end)
    path.write_text(content[:head_end] + "\n" + text + "\n" + content[stop:])


def _to_stderr(message: str) -> None:
    print(f"  {message}", file=sys.stderr, flush=True)


def parser_for(study: Study, prog: str, description: str | None = None) -> argparse.ArgumentParser:
    """The study's command line: --json, --quick, --readme (a study with a block) and its own flags."""
    parser = argparse.ArgumentParser(prog=prog, description=description,
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    if study.quick is not None:
        parser.add_argument("--quick", action="store_true", help=study.quick)
    else:
        parser.set_defaults(quick=False)
    parser.add_argument("--readme", default=None, metavar="FILE",
                        help="rewrite the study's block of this Markdown file with the result")
    study.add_arguments(parser)
    return parser


def report_block(study: Study, result: dict, command: str) -> str:
    """The default block: the command that ran and its report, preformatted."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        study.report(result)
    return f"`{command}`:\n\n```\n{out.getvalue().rstrip()}\n```"


def _command(prog: str, argv: list[str]) -> str:
    """The command line that ran, without --readme FILE (the block says what produced it)."""
    kept, skip = [], False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--readme":
            skip = True
        elif not arg.startswith("--readme="):
            kept.append(arg)
    return " ".join([prog, *kept])


def run(study: Study, argv: list[str] | None, prog: str, name: str) -> int:
    """Parse argv (None: the process's arguments) for `study`, registered as `name`, run it, print
    its result; the exit status (2: bad input, named)."""
    argv = sys.argv[1:] if argv is None else argv
    args = parser_for(study, prog, STUDIES[name][1]).parse_args(argv)
    try:
        result = study.run(args, None if args.json else _to_stderr)
        if args.readme:
            if study.block is not None:
                write_block(args.readme, study.block[0], study.block[1](result, Path(args.readme)))
            else:
                write_block(args.readme, name, report_block(study, result, _command(prog, argv)))
    except ValueError as err:
        print(f"{prog}: {err}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(to_json(result)))
    else:
        study.report(result)
    return 0
