"""µs per net tick (NetSim.step, 1 ms) for several net sizes: awake, ball near, impact; full / culled sweep loop / NetSim.

Run: `.venv/bin/python bench/net_tick.py [--ticks 200] [--json]` (net_kernel.profile.tick_costs).
"""
import argparse
import json

from net_kernel.profile import SWEEPS, tick_costs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--ticks", type=int, default=200, help="ticks per timed run")
    parser.add_argument("--sizes", default="184x16,92x8,70x7", help="nets, COLSxROWS, comma-separated")
    parser.add_argument("--clock", choices=("thread", "wall"), default="thread",
                        help="thread: CPU time of the stepping thread; wall: elapsed time")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.sizes.split(",")]
    report = tick_costs(sizes=sizes, ticks=args.ticks, clock=args.clock)
    if args.json:
        print(json.dumps(report))
        return
    print(f"µs per 1 ms net tick, {report['clock']} clock (median of {report['repeats']} runs of {report['ticks']} "
          f"ticks; load average {report['load_avg']:.2f}); NetSim's substep loop with the full / the culled contact "
          "sweep / NetSim as it is")
    print(f"  {'net':>7} {'knots':>6} {'substeps':>8} {'awake':>20} {'ball near':>20} {'impact':>20}")
    for r in report["rows"]:
        cells = [" / ".join(f"{r[f'{c}_{sweep}_us']:.0f}" for sweep in SWEEPS) for c in ("awake", "near", "impact")]
        print(f"  {r['cols']}x{r['rows']:<3} {r['knots']:>6} {r['substeps']:>8} {cells[0]:>20} {cells[1]:>20} "
              f"{cells[2]:>20}")


if __name__ == "__main__":
    main()
