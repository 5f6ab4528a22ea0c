"""What `pingpong stress` reports: latency and tick jitter against the tick schedule, percentiles,
and the table and lines a user reads."""
from __future__ import annotations

import json
import os

import numpy as np


def percentiles_ms(values: np.ndarray) -> dict:
    if len(values) == 0:
        return {"p50": None, "p99": None, "max": None, "n": 0}
    ms = values * 1000.0
    return {"p50": round(float(np.percentile(ms, 50)), 3), "p99": round(float(np.percentile(ms, 99)), 3),
            "max": round(float(ms.max()), 3), "n": int(len(ms))}


def tick_schedule(clock: dict, dt: float):
    """Per physics incarnation (pid): first time seen, and the schedule's base (lower envelope of
    seen - tick*dt, the incarnation's first sample left out: it may predate the start)."""
    ticks, times, pids = clock["ticks"], clock["times"], clock["pids"]
    segments = []
    for pid in dict.fromkeys(pids.tolist()):
        idx = np.flatnonzero(pids == pid)
        if len(idx) < 3:
            continue
        idx = idx[1:]
        offsets = times[idx] - ticks[idx] * dt
        segments.append((float(times[idx[0]]), float(offsets.min()), idx))
    return segments


def jitter(clock: dict | None, dt: float, t0: float, t1: float) -> dict:
    """Lateness of each tick the clock saw inside [t0, t1] against its incarnation's schedule."""
    if clock is None:
        return {"p99": None, "max": None, "n": 0}
    late = []
    for _, base, idx in tick_schedule(clock, dt):
        times, ticks = clock["times"][idx], clock["ticks"][idx]
        keep = (times >= t0) & (times <= t1)
        late.append(times[keep] - (base + ticks[keep] * dt))
    values = np.concatenate(late) if late else np.zeros(0)
    out = percentiles_ms(values)
    duration = float(clock["times"][-1] - clock["times"][0]) if len(clock["times"]) > 1 else 0.0
    out["resolution_ms"] = round(1000 * duration / max(int(clock["samples"]), 1), 3)
    out["ticks_seen_pct"] = round(100.0 * len(values) / max((t1 - t0) / dt, 1), 1)
    return out


def latency_values(clock: dict | None, dt: float, records: list[str]) -> np.ndarray:
    """s, receipt time minus the scheduled publish time of the snapshot's tick, every snapshot of
    the records (.npz of ticks and times) since the match started. The schedule, not the time the
    server actually sent, so a client (or server) that fell behind is charged for every snapshot
    it delayed: no coordinated omission."""
    if clock is None:
        return np.zeros(0)
    segments = tick_schedule(clock, dt)
    if not segments:
        return np.zeros(0)
    starts = np.array([s[0] for s in segments])
    bases = np.array([s[1] for s in segments])
    values = []
    for path in records:
        if not os.path.exists(path):
            continue
        with np.load(path) as data:
            ticks, times = data["ticks"], data["times"]
        playing = times >= starts[0]  # snapshots of tick 0 while the match waited for its players: no schedule yet
        ticks, times = ticks[playing], times[playing]
        which = np.searchsorted(starts, times, side="right") - 1
        values.append(times - (bases[which] + ticks * dt))
    return np.concatenate(values) if values else np.zeros(0)


def gateway_latency(clock: dict | None, send_log: np.ndarray | None) -> dict:
    """The gateway's own part of a spectator's latency, in ms: from the time the physics' tick came
    out (the tick clock's first sight of it, or of the first later tick it saw) to the gateway's
    send of that tick's snapshot (its send log), for every snapshot of a new tick (a standing
    clock's tick sent again is not a new one)."""
    if clock is None or send_log is None or not len(send_log) or not len(clock["ticks"]):
        return percentiles_ms(np.zeros(0))
    seen_ticks, first = np.unique(clock["ticks"], return_index=True)
    seen_at = clock["times"][first]
    ticks, sent = send_log[:, 0].astype(np.int64), send_log[:, 1]
    new = np.concatenate(([True], ticks[1:] != ticks[:-1])) & (ticks > 0)
    ticks, sent = ticks[new], sent[new]
    which = np.searchsorted(seen_ticks, ticks)
    inside = which < len(seen_ticks)
    return percentiles_ms(sent[inside] - seen_at[which[inside]])


def latency(values_s: np.ndarray) -> dict:
    """Percentiles of latency_values, in ms."""
    return percentiles_ms(values_s)


def plot_load(directory: str, values_s: np.ndarray, records: list[str], hz: int, spectators: int,
              timed: int) -> dict:
    """Two PNGs of a load run in `directory`: the latency CDF (log time axis) and the snapshot rate
    per spectator, second by second (the timed spectators' receipts in each second over their
    number: the records hold theirs), against the target rate. Returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(directory, exist_ok=True)
    paths = {"latency_cdf": os.path.join(directory, "load-latency-cdf.png"),
             "rate": os.path.join(directory, "load-rate.png")}
    fig, ax = plt.subplots(figsize=(6, 4))
    if len(values_s):
        ms = np.sort(np.maximum(values_s * 1000.0, 1e-3))
        ax.plot(ms, np.arange(1, len(ms) + 1) / len(ms))
        ax.set_xscale("log")
    ax.axvline(5.0, color="grey", linestyle="--", label="5 ms")
    ax.set_xlabel("latency from the tick's scheduled time (ms)")
    ax.set_ylabel("fraction of snapshots")
    ax.set_title(f"latency CDF, {spectators} spectators at {hz} Hz ({len(values_s)} snapshots)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(paths["latency_cdf"], dpi=100)
    plt.close(fig)
    times = [np.load(p)["times"] for p in records if os.path.exists(p)]
    times = np.concatenate(times) if times else np.zeros(0)
    fig, ax = plt.subplots(figsize=(6, 4))
    if len(times):
        t = times - times.min()
        counts, edges = np.histogram(t, bins=np.arange(0.0, np.ceil(t.max()) + 1.0))
        ax.step(edges[:-1], counts / max(timed, 1), where="post", label=f"received, mean of {timed} timed spectators")
    ax.axhline(hz, color="grey", linestyle="--", label=f"{hz} Hz")
    ax.set_xlabel("s since the first snapshot")
    ax.set_ylabel("snapshots per second per spectator")
    ax.set_title("snapshot rate, second by second")
    ax.legend()
    fig.tight_layout()
    fig.savefig(paths["rate"], dpi=100)
    plt.close(fig)
    return paths


def _fmt(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, dict):
        return "/".join(_fmt(value.get(k)) for k in ("p50", "p99", "max") if k in value)
    return str(value)


def _summary(result: dict) -> str:
    c = result["counts"]
    name = result["scenario"]
    if name == "load":
        return (f"{c.get('welcomed')}/{c.get('spectators')} spectators at {c.get('snapshot_hz')} Hz "
                f"({c.get('fanout')} fan-out, {c.get('on_feed')} on the feed), rate median "
                f"{c.get('rate_median_hz')} min {c.get('rate_min_hz')} Hz, missed {c.get('snapshots_missed')} "
                f"(feed gaps {c.get('feed_missed')}, gateway dropped {c.get('gateway_snapshots_dropped')}), "
                f"{c.get('points')} points")
    if name == "churn":
        return (f"{c.get('cycles')} cycles in {c.get('seconds')} s ({c.get('cycles_per_s')}/s), "
                f"{c.get('left_abrupt', 0)} without goodbye; fill after: {c.get('fill_welcomed')} welcomed, "
                f"rejected {c.get('fill_rejected')}")
    if name == "cable":
        return (f"pulled {c.get('pulled_slot')}: grace newcomer {c.get('during_grace_newcomer')}, goodbye "
                f"{c.get('pulled_goodbye')}, token -> {c.get('token_rejoin')}; silent: after grace -> "
                f"{c.get('after_grace_newcomer')} in {c.get('freed_after_s')} s")
    if name == "kill":
        return (f"{c.get('client_processes_killed')} client processes, gateway restarted {c.get('gateway_restarted')},"
                f" physics restarted {c.get('physics_restarted')}, rejoined {c.get('keep_rejoined')}; shutdown: "
                f"{c.get('goodbye_shutdown')}/{c.get('clients_at_shutdown')} goodbyes")
    if name == "malformed":
        return (f"{c.get('sent')} sent, gateway dropped {c.get('gateway_dropped_total')} (expected "
                f"{c.get('expected_dropped_total')}), {c.get('kicks')} kicks, legit {c.get('legit_goodbyes')}")
    return json.dumps(c)[:120]


def print_table(results: list[dict]) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title="pingpong stress")
    for column in ("scenario", "ok", "crashes", "lost points", "leaked fds", "leaked shm", "RSS growth %"):
        table.add_column(column, no_wrap=column == "scenario")
    for r in results:
        table.add_row(r["scenario"], "yes" if r["ok"] else "NO", str(r["crashes"]), str(r["lost_points"]),
                      str(r["leaked_fds"]), str(r["leaked_shm"]), _fmt(r["rss_growth_pct"]))
    console = Console()
    console.print(table)
    for r in results:
        jit = r.get("tick_jitter_ms") or {}
        timing = (f"; latency ms p50/p99/max {_fmt(r['latency_ms'])}, the gateway's own "
                  f"{_fmt(r.get('gateway_latency_ms'))}, tick jitter ms p99/max "
                  f"{_fmt(jit.get('p99'))}/{_fmt(jit.get('max'))}" if r.get("latency_ms") else "")
        console.print(f"[bold]{r['scenario']}[/]: {_summary(r)}{timing}; load average before/after "
                      f"{r.get('loadavg_before_after')}")
    for r in results:
        if r.get("cpu_pct"):
            console.print(f"[bold]{r['scenario']}[/] CPU % of one core: " +
                          ", ".join(f"{k} {v}" for k, v in r["cpu_pct"].items()))
        if r.get("cpu_pct_by_side"):
            console.print(f"[bold]{r['scenario']}[/] CPU % of one core by side: " +
                          ", ".join(f"{k} {v}" for k, v in r["cpu_pct_by_side"].items()))
        swarm = r.get("swarm")
        if swarm:
            console.print(f"[bold]{r['scenario']}[/] swarm: {swarm['cpu_us_per_message']} us CPU per message "
                          f"received (by thread {swarm['cpu_us_per_message_by_thread']}), receive loops busy up "
                          f"to {swarm['busy_pct_max']} %, wanting a CPU up to {swarm['demand_pct_max']} % "
                          f"({swarm['runqueue_wait_pct_max']} % waiting for one), backlog p99 {swarm['backlog_p99_max']} (max "
                          f"{swarm['backlog_max']}), bulk reads late p50 up to {swarm['bulk_lag_p50_ms_max']} ms, "
                          f"longest turn {swarm['turn_max_ms']} ms; CPU % of one core {swarm['cpu_pct']}")
            if r.get("limited_by_load_generator"):
                console.print(f"[yellow]{r['scenario']}: limited by the load generator[/]")
        for path in (r.get("plots") or {}).values():
            console.print(f"[bold]{r['scenario']}[/] plot: {path}")
        for problem in r["problems"]:
            console.print(f"[red]{r['scenario']}: {problem}[/]")
        for finding in r.get("findings", []):
            console.print(f"[yellow]{r['scenario']}: finding: {finding}[/]")

