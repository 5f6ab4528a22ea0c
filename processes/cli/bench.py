"""`pingpong bench STUDY`: thin front end to the studies in bench/ (parse, call, format), and to
the match benchmark (processes.cli.match).

The studies live in bench/accuracy.py, bench/effects.py, bench/net_resolution.py, bench/net_tail.py and bench/ringdown.py,
next to the pytest-benchmark suite, and need a source checkout (bench/ is not an installed package) and the dev extras (scipy).
"""
from __future__ import annotations

import importlib
import json
import math
import sys
from pathlib import Path
from processes.cli.common import FORMATTER

ROOT = Path(__file__).resolve().parents[2]


def load_study(name: str):
    """Import bench/<name>.py from the checkout this package was installed from (editable)."""
    if not (ROOT / "bench" / f"{name}.py").exists():
        raise SystemExit(f"pingpong bench {name}: bench/{name}.py not found next to {ROOT / 'processes'}; "
                         "the studies need a source checkout (make bench)")
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    return importlib.import_module(f"bench.{name}")


def finite_json(value):
    """value with every non-finite float replaced by None (JSON has no infinity: a missed impact)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): finite_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_json(v) for v in value]
    if hasattr(value, "item"):  # numpy scalars
        return finite_json(value.item())
    return value


def _progress(quiet: bool):
    if quiet:
        return None
    return lambda msg: print(f"  {msg}", file=sys.stderr, flush=True)


def _print_accuracy(study, result: dict) -> None:
    from rich.console import Console
    from rich.markdown import Markdown

    console = Console()
    ref = result["reference"]
    console.print(f"[bold]Work-precision study[/bold]: {len(result['shots'])} shots against scipy DOP853 at "
                  f"rtol = atol = {ref['tol']:.0e} (reference built in {ref['seconds']:.1f} s; kernels compiled or "
                  f"loaded in {result['compile_seconds']:.1f} s, apart from every timing)")
    for name, check in ref["shots"].items():
        console.print(f"  {name}: bounces {', '.join(check['bounces'])} at "
                      f"{', '.join(f'{t:.3f}' for t in check['impact_times_s'])} s; reference at "
                      f"{ref['check_tol']:.0e} agrees to {max(check['landing_diff_m'], check['final_diff_m']):.1e} m")
    console.print(Markdown(study.markdown_table(result)))
    console.print(f"timing: median of {result['repeats']}; spread between repeats median "
                  f"{result['timing_spread_median'] * 100:.0f} %, worst {result['timing_spread_max'] * 100:.0f} % "
                  "(2 shared cores: read the ratios, not the absolute times)")
    step = result["through_step_1ms"]
    console.print("through engine.world.step, 1 ms tick: "
                  + ", ".join(f"{name} {v['us_per_tick']:.1f} µs/tick" for name, v in step.items()))
    console.print(Markdown(study.orders_markdown(result)))
    for line in result["findings"]:
        console.print(f"- {line}")
    console.print(Markdown(study.recommendation_markdown(result)))
    console.print(Markdown(study.net_markdown(result)))


def _print_effects(result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    console.print(f"[bold]Effect costs[/bold], scene {result['scene']}: numba tick loop over {result['sim_seconds']:g} "
                  f"simulated s, median of {result['repeats']} interleaved rounds; kernels compiled in "
                  f"{result['compile_seconds']:.1f} s, apart. Same-run A/A check of the baseline: "
                  f"{result['noise']['aa_ratio']:.3f} (median spread between rounds {result['noise']['spread'] * 100:.0f} %).")
    table = Table("effect", "without s/sim s", "with s/sim s", "with / without", "fastest rounds", "absent compiled out")
    notes = []
    for row in result["effects"]:
        if not row["available"] or row.get("skipped"):
            table.add_row(row["effect"], "-", "-", "-", "-", "-")
            notes.append(f"{row['effect']}: {'not available: ' if not row['available'] else ''}{row['note']}")
            continue
        fastest = row.get("ratio_fastest_rounds")
        compiled = {True: "yes", False: "no", None: "-"}[row.get("compiled_out")]
        table.add_row(row["effect"], f"{row['without_s_per_sim_s']:.2e}", f"{row['with_s_per_sim_s']:.2e}",
                      f"{row['ratio']:.2f}", "-" if fastest is None else f"{fastest:.2f}", compiled)
        notes.append(f"{row['effect']}: {row['note']}")
    console.print(table)
    for note in notes:
        console.print(f"  {note}")
    if result.get("absent_check"):
        console.print(f"absent costs nothing: {result['absent_check']['text']}")


def _parse_sizes(text: str | None):
    """[(cols, rows), ...] from "COLSxROWS,..." or None; a bad entry exits with a message naming it."""
    if text is None:
        return None
    sizes = []
    for item in text.split(","):
        parts = item.strip().lower().split("x")
        if len(parts) != 2 or not all(p.isdigit() for p in parts) or min(int(p) for p in parts) < 2:
            raise SystemExit(f"pingpong bench net-resolution: --sizes entry {item!r} is not COLSxROWS with "
                             "integers >= 2 (e.g. --sizes 70x7,92x8,184x16)")
        sizes.append((int(parts[0]), int(parts[1])))
    if len(sizes) < 2:
        raise SystemExit("pingpong bench net-resolution: --sizes needs at least two nets (the finest is the reference)")
    return sizes


def _print_net_resolution(study, result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    console.print(f"[bold]Net resolution: accuracy against cost[/bold] (the same physical net on each grid, "
                  f"net_kernel.topology.resolution_spec; errors against {result['reference']}; every column in "
                  "--json and in bench/net_resolution.py's Markdown table; sub: substeps a tick, !: the ball fits through a "
                  "cell; errors: median exit velocity error, mean differences of speed, first contact and bulge)")
    table = Table(*study.COMPACT_COLUMNS)
    for cells in study.compact_rows(result):
        table.add_row(*cells)
    console.print(table)
    for line in study.summary_lines(result):
        console.print(f"- {line}")


def bench_command(args) -> int:
    """Run `pingpong bench STUDY`; returns the exit status."""
    if args.what == "handoff":
        return load_study("handoff").handoff_command(args)
    if args.what == "match":
        from processes.cli.match import bench_match_command

        return bench_match_command(args)
    return _study_command(args)


def _study_command(args) -> int:
    """Run `pingpong bench accuracy`, `effects`, `net-resolution` or `ringdown`; returns the exit status."""
    quick = bool(getattr(args, "quick", False))
    as_json = bool(getattr(args, "json", False))
    if args.what == "accuracy":
        study = load_study("accuracy")
        result = study.study(quick=quick, progress=_progress(as_json))
        if getattr(args, "png", None):
            study.plot(result, args.png)
            result["png"] = args.png
        if as_json:
            print(json.dumps(finite_json(result)))
        else:
            _print_accuracy(study, result)
            if getattr(args, "png", None):
                print(f"work-precision plot: {args.png}")
        return 0
    if args.what == "effects":
        study = load_study("effects")
        result = study.study(quick=quick, progress=_progress(as_json))
        if as_json:
            print(json.dumps(finite_json(result)))
        else:
            _print_effects(result)
        return 0
    if args.what == "net-resolution":
        sizes = _parse_sizes(getattr(args, "sizes", None))
        impacts = getattr(args, "impacts", None)
        if impacts is not None and impacts < 1:
            raise SystemExit(f"pingpong bench net-resolution: --impacts {impacts} must be >= 1")
        study = load_study("net_resolution")
        try:
            result = study.study(quick=quick, sizes=sizes, n_impacts=impacts, progress=_progress(as_json))
        except ValueError as err:  # a net resolution_spec cannot build, named by the message
            raise SystemExit(f"pingpong bench net-resolution: {err}") from None
        if as_json:
            print(json.dumps(finite_json(result)))
        else:
            _print_net_resolution(study, result)
        return 0
    if args.what == "net-tail":
        study = load_study("net_tail")
        result = study.study(quick=quick, progress=_progress(as_json))
        if as_json:
            print(json.dumps(finite_json(result)))
        else:
            print(study.text(result))
        return 0
    if args.what == "ringdown":
        study = load_study("ringdown")
        result = study.study(quick=quick, progress=_progress(as_json))
        if as_json:
            print(json.dumps(finite_json(result)))
        else:
            _print_ringdown(study, result)
        return 0
    raise SystemExit(f"pingpong bench: unknown study {args.what!r}")


def _print_ringdown(study, result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(width=max(Console().width, 140))  # twelve columns: wider than a pipe's default 80
    table = Table("net", "air 1/s", "point", "m/s", "asleep s", "awake ticks", "net CPU s", "peak mm", "absorbed mJ",
                  "ring Hz", "zeta", "zeta model")
    for name, net in result["nets"].items():
        for shot in net["shots"]:
            asleep = f"{shot['sleep_s']:.2f}" if math.isfinite(shot["sleep_s"]) else f"> {shot['stepped_s']:g}"
            table.add_row(name, f"{net['air_damping_per_s']:g}", shot["point"], f"{shot['speed_m_s']:g}", asleep,
                          str(shot["awake_ticks"]), f"{shot['net_cpu_s']:.2f}",
                          f"{shot['peak_deflection_m'] * 1e3:.1f}", f"{shot['energy_absorbed_J'] * 1e3:.1f}",
                          f"{shot['ring_frequency_hz']:.1f}", f"{shot['damping_ratio']:.4f}",
                          f"{shot['damping_ratio_model']:.4f}")
    console.print(table)
    console.print(f"kernels compiled or loaded in {result['compile_s']:.1f} s, apart from every shot's net CPU")
    for line in study.summary_lines(result):
        console.print(f"- {line}")


def add_commands(sub) -> None:
    """`pingpong bench STUDY`."""
    bench = sub.add_parser("bench", help="measured answers to 'what does it cost'", formatter_class=FORMATTER)
    bench.add_argument("what", choices=["accuracy", "effects", "handoff", "match", "net-resolution", "net-tail",
                                        "ringdown"],
                       help="which study to run")
    bench.add_argument("--best-of", type=int, default=5, help="match: games in the benchmarked match")
    bench.add_argument("--scene", default="match",
                       help="match: scene TOML files or bundled scene names, comma-separated, run back to back "
                            "(match: the cloth net, match_air: it damped by the air alone, match_rigid: the rigid net)")
    bench.add_argument("--seed", type=int, default=0, help="match: the match's seed")
    bench.add_argument("--ticks", type=int, default=None,
                       help="match: stop each match after this many ticks (default: the scene's bound; --quick: 20000)")
    bench.add_argument("--json", action="store_true", help="print one JSON object")
    bench.add_argument("--png", default=None, help="accuracy: write the work-precision plot to this PNG file")
    bench.add_argument("--quick", action="store_true", help="fewer step sizes and repeats (smoke runs)")
    bench.add_argument("--sizes", default=None,
                       help="net-resolution: nets as COLSxROWS, comma-separated (the finest is the reference)")
    bench.add_argument("--impacts", type=int, default=None, help="net-resolution: number of impacts")
    bench.set_defaults(func=bench_command)
