"""`pingpong profile-net`: the net kernel's cost against this machine's copy bandwidth.

The study's flags, run and report; the measuring (bench/net_costs.py, numba) is imported when it
runs, so `pingpong profile-net --help` loads none of it.
"""
from bench.study import Study
from bench.study import run as run_study


def parse_knots(text: str) -> tuple[int, int]:
    """(cols, rows) from "COLSxROWS"; ValueError with the expected form otherwise."""
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise ValueError(f"--knots {text!r}: expected COLSxROWS, e.g. 184x16")
    return int(parts[0]), int(parts[1])


def _arguments(parser) -> None:
    parser.add_argument("--knots", default="184x16", help="knot grid, COLUMNSxROWS")
    parser.add_argument("--steps", type=int, default=None, help="timed steps (default: sized to ~1 s per backend)")
    parser.add_argument("--backend", choices=["numba", "reference", "both"], default="both")
    parser.add_argument("--path", choices=["grid", "grid32", "grid32_fma", "csr", "all"], default="all",
                        help="kernel path: the grid kernel NetSim uses (float64), its float32 variants, the general "
                             "CSR kernel, or all")


def _run(args, progress=None) -> dict:
    """The profile for args.knots/steps/backend/path; ValueError names a malformed flag."""
    from bench.net_costs import PATHS, profile_net

    cols, rows = parse_knots(args.knots)
    if args.steps is not None and args.steps < 1:
        raise ValueError(f"--steps {args.steps}: must be >= 1")
    backends = ("numba", "reference") if args.backend == "both" else (args.backend,)
    paths = PATHS if args.path == "all" else (args.path,)
    return profile_net(cols, rows, steps=args.steps, backends=backends, paths=paths)


def print_profile(report: dict) -> None:
    """The profile as a table, then the grid kernel's anatomy."""
    print(f"net {report['cols']} x {report['rows']}: {report['knots']} knots, {report['springs']} springs "
          f"(structural + shear), h = {report['h_s']:.3g} s ({report['substeps_per_tick']} substeps a 1 ms tick)")
    print(f"numba threads: {report['threads']} ({report['threading_layer']}); load average "
          f"{report['load_avg'][0]:.2f} before, {report['load_avg'][1]:.2f} after (a shared machine slows everything)")
    copy = report["copy"]
    print(f"copy bandwidth (numpy copy of {copy['bytes'] / 2**21:.0f} MiB, read + write): "
          f"{copy['gb_per_s']:.1f} GB/s (before {copy['before']:.1f}, after {copy['after']:.1f})")
    print(f"byte model: {report['byte_model']}")
    header = (f"  {'path':<10} {'backend':<18} {'compile s':>9} {'steps':>7} {'per call':>8} {'µs/step':>10} "
              f"{'[min .. max]':>22} {'cpu µs/step':>11} {'Msprings/s':>11} {'GB/s':>7} {'of copy':>8} {'x textbook':>10}")
    print(header)
    for r in report["results"]:
        name = r["backend"] + (" parallel" if r["parallel"] else " serial" if r["backend"] == "numba" else "")
        spread = f"[{r['us_per_step_min']:.1f} .. {r['us_per_step_max']:.1f}]"
        cpu = "-" if r["cpu_us_per_step"] is None else f"{r['cpu_us_per_step']:.1f}"
        print(f"  {r['path']:<10} {name:<18} {r['compile_s']:>9.2f} {r['steps']:>7} {r['steps_per_call']:>8} "
              f"{r['us_per_step']:>10.1f} {spread:>22} {cpu:>11} {r['msprings_per_s']:>11.1f} {r['gb_per_s']:>7.2f} "
              f"{100 * r['copy_share']:>7.1f}% {_ratio(r):>10}")
    print(f"  median of {report['results'][0]['repeats']} timed runs each; cpu µs/step: the stepping thread's CPU "
          "time (serial kernels; time waiting for a core left out); compile time is the first call's "
          "excess over the second (0 when numba's cache is warm); grid: a tick's substeps per call, as NetSim "
          "steps a net the ball is away from; grid32, grid32_fma: the grid kernel in float32 on offsets from the built grid "
          "(NetSpec kernel_precision = 'float32', kernel_fma off and on); csr: one step per call; scatter: the textbook per-spring scatter "
          "loop (kernels.step_knots_scatter), serial, one step per call; x textbook: its cpu µs/step over the "
          "row's (µs/step for parallel rows), same net, same run")
    _print_anatomy(report)


def _ratio(r: dict) -> str:
    return "-" if r.get("textbook_ratio") is None else f"{r['textbook_ratio']:.1f}x"


def _print_anatomy(report: dict) -> None:
    """The grid kernel's passes timed apart, and each kernel's loops' vector width."""
    passes = report.get("passes")
    if passes:
        print(f"grid kernel's passes (step_grid_serial's loops alone, this thread's CPU time, best of 5), "
              f"{passes['rows']} x {passes['cols']}: µs per step, ns per spring or knot, and ns on rows 8x longer")
        for name, (us, count, unit) in passes["passes"].items():
            long_rows = passes["long_rows"][name] if passes["long_rows"] else None
            longer = "-" if long_rows is None else f"{1e3 * long_rows[0] / long_rows[1]:.2f}"
            print(f"  {name:<36} {us:>8.2f} µs {1e3 * us / count:>7.2f} ns/{unit:<6} {longer:>7} on long rows")
        print(f"  {'step_grid_serial':<36} {passes['step_us']:>8.2f} µs; outside the passes "
              f"{passes['rest_us']:.2f} µs; the divider's floor (a root and a division per spring, float64) "
              f"{passes['divider_floor_us']:.2f} µs")
        print(f"  floors: the springs' arithmetic alone (contiguous rows, as many springs) "
              f"{passes['spring_floor_us']:.2f} µs; the same without the divider (float32 root and division, one "
              f"float64 Newton step) {passes['spring_floor_no_divider_us']:.2f} µs")
    vectors = report.get("vectors")
    if vectors:
        print("vectorised? each kernel's widest loop, from numba's assembly (float64 lanes: xmm 2, ymm 4, zmm 8; "
              "float32, /f32: twice as many)")
        for name, v in vectors.items():
            packed = "scalar only" if v["lanes"] == 1 else f"packed {v['width']} x{v['lanes']}, {v['packed_ops']} ops"
            print(f"  {name:<40} {packed:<28} {v['scalar_loops']} of {v['loops']} loops scalar only")
    awake = report.get("awake_ticks")
    if awake:
        print(f"awake NetSim tick of the match's {awake['cols']} x {awake['rows']} net (resolution_spec, ball away, "
              f"{awake['substeps']} substeps; this thread's CPU time, median of {awake['repeats']} runs of "
              f"{awake['ticks']} ticks, interleaved): µs per tick, and float64's over it")
        for name, us in awake["us"].items():
            print(f"  {name:<12} {us:>8.1f} µs {awake['ratio'][name]:>6.2f}x")


STUDY = Study(run=_run, report=print_profile, add_arguments=_arguments, quick=None)

if __name__ == "__main__":
    raise SystemExit(run_study(STUDY, None, "python -m bench.profile_net", "profile-net"))
