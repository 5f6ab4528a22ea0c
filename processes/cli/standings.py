"""Standings of many matches: win rates with Wilson intervals, Elo with bootstrap intervals,
how each profile lost its points and how long its rallies were, and their plots.

Undecided matches (stopped by a tick bound) count in the rally statistics, not in the win
rates or ratings.
"""
from __future__ import annotations

import math

import numpy as np

Z_95 = 1.959963984540054  # standard normal quantile for a two-sided 95 % interval
ELO_BASE = 1500.0  # the mean rating (logarithmic mean of the strengths)
ELO_SCALE = 400.0  # Elo points per factor 10 in odds (Elo 1978, the FIDE scale)
BOOTSTRAP = 1000  # resamples of the matches for the rating intervals
BOOTSTRAP_SEED = 0  # fixed: the same records give the same intervals
PRIOR_WINS = 0.5  # virtual wins each way for every pair that met, so a clean sweep has a finite rating
MM_ITERATIONS = 500  # Hunter's MM converges linearly; 500 leaves < 1e-9 relative change for a few profiles


def wilson(wins: int, n: int, z: float = Z_95) -> tuple[float, float] | None:
    """Wilson's score interval for a binomial proportion (E. B. Wilson, JASA 22, 209, 1927);
    None for n = 0."""
    if n == 0:
        return None
    p = wins / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (max(0.0, centre - half), min(1.0, centre + half))


def _winner_loser(record: dict) -> tuple[str, str] | None:
    if record["winner"] is None:
        return None
    won = record[record["winner"]]
    lost = record["b" if record["winner"] == "a" else "a"]
    return won, lost


def win_matrix(records: list[dict], profiles: list[str]) -> dict:
    """rate[i][j]: the share of decided matches between profiles i and j (both ends) that i won,
    with its Wilson interval; None where they did not meet (and on the diagonal)."""
    index = {p: k for k, p in enumerate(profiles)}
    n = len(profiles)
    wins = [[0] * n for _ in range(n)]
    for record in records:
        pair = _winner_loser(record)
        if pair is not None and pair[0] != pair[1]:
            wins[index[pair[0]]][index[pair[1]]] += 1
    rate = [[None] * n for _ in range(n)]
    low = [[None] * n for _ in range(n)]
    high = [[None] * n for _ in range(n)]
    for i in range(n):
        for j in range(n):
            games = wins[i][j] + wins[j][i]
            if i != j and games:
                rate[i][j] = wins[i][j] / games
                low[i][j], high[i][j] = wilson(wins[i][j], games)
    decided = sum(map(sum, wins))
    return {"profiles": profiles, "wins": wins, "rate": rate, "low": low, "high": high, "decided": decided}


def _bradley_terry(wins: np.ndarray) -> np.ndarray:
    """Strengths p (shape (..., n)) maximising the Bradley-Terry likelihood of wins[..., i, j]
    (i beat j), by Hunter's MM iteration (D. R. Hunter, Ann. Statist. 32, 384, 2004, eq. 3),
    normalised to a geometric mean of 1."""
    games = wins + np.swapaxes(wins, -1, -2)
    won = wins.sum(axis=-1)
    strength = np.ones(wins.shape[:-1])
    for _ in range(MM_ITERATIONS):
        pair_sum = strength[..., :, None] + strength[..., None, :]
        strength = won / (games / pair_sum).sum(axis=-1)
        strength /= np.exp(np.log(strength).mean(axis=-1, keepdims=True))
    return strength


def elo(records: list[dict], profiles: list[str]) -> dict:
    """Elo ratings fitted to all decided matches at once (Bradley-Terry maximum likelihood on the
    Elo scale, so the order of the matches does not matter), with 95 % percentile intervals from
    BOOTSTRAP resamples of the matches. A profile without a decided match against another has none."""
    index = {p: k for k, p in enumerate(profiles)}
    games = [(index[w], index[lost]) for w, lost in filter(None, map(_winner_loser, records)) if w != lost]
    rated = sorted({k for pair in games for k in pair})
    out: dict = {p: None for p in profiles}
    if len(rated) < 2:
        return out
    where = {k: r for r, k in enumerate(rated)}
    pairs = np.array([(where[w], where[lost]) for w, lost in games], np.int64)
    met = np.zeros((len(rated), len(rated)))
    met[pairs[:, 0], pairs[:, 1]] = met[pairs[:, 1], pairs[:, 0]] = PRIOR_WINS

    def wins_of(samples: np.ndarray) -> np.ndarray:  # samples: (resamples, matches) indices into pairs
        wins = np.broadcast_to(met, (len(samples), *met.shape)).copy()
        chosen = pairs[samples]
        np.add.at(wins, (np.arange(len(samples))[:, None], chosen[..., 0], chosen[..., 1]), 1.0)
        return wins

    to_elo = lambda strength: ELO_BASE + ELO_SCALE * np.log10(strength)  # noqa: E731
    rating = to_elo(_bradley_terry(wins_of(np.arange(len(pairs))[None, :])))[0]
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    boot = to_elo(_bradley_terry(wins_of(rng.integers(0, len(pairs), (BOOTSTRAP, len(pairs))))))
    low, high = np.percentile(boot, [2.5, 97.5], axis=0)
    for r, k in enumerate(rated):
        out[profiles[k]] = {"elo": float(rating[r]), "low": float(low[r]), "high": float(high[r])}
    return out


def per_profile(records: list[dict], profiles: list[str]) -> dict:
    """Per profile: matches, wins, the reasons of the points it lost, its rallies' mean length."""
    out = {p: {"matches": 0, "won": 0, "undecided": 0, "points_won": 0, "points_lost": 0, "lost_by": {},
               "rally_shots_sum": 0.0} for p in profiles}
    for record in records:
        total_points = sum(record["points"])
        for end, mine, theirs in (("a", 0, 1), ("b", 1, 0)):
            row = out[record[end]]
            row["matches"] += 1
            row["won"] += record["winner"] == end
            row["undecided"] += record["winner"] is None
            row["points_won"] += record["points"][mine]
            row["points_lost"] += record["points"][theirs]
            row["rally_shots_sum"] += record["mean_rally_shots"] * total_points
            for reason, count in record["reasons"][end].items():
                row["lost_by"][reason] = row["lost_by"].get(reason, 0) + count
    for row in out.values():
        points = row["points_won"] + row["points_lost"]
        row["mean_rally_shots"] = row.pop("rally_shots_sum") / points if points else None
        row["lost_by"] = dict(sorted(row["lost_by"].items(), key=lambda kv: -kv[1]))
    return out


def end_a(records: list[dict]) -> dict:
    """End A's share of the decided matches with its Wilson interval (the ends' balance, or one
    pairing's result)."""
    decided = [r for r in records if r["winner"] is not None]
    wins = sum(r["winner"] == "a" for r in decided)
    interval = wilson(wins, len(decided))
    return {"decided": len(decided), "wins": wins, "rate": wins / len(decided) if decided else None,
            "low": interval and interval[0], "high": interval and interval[1]}


def standings(records: list[dict], profiles: list[str]) -> dict:
    """Everything a tournament reports about its records."""
    sim = sum(r["sim_seconds"] for r in records)
    wall = sum(r["wall_seconds"] for r in records)
    return {"ratings": elo(records, profiles), "matrix": win_matrix(records, profiles),
            "profiles": per_profile(records, profiles), "end_a": end_a(records),
            "realtime_factor": sim / wall if wall > 0 else None}


def labels(profiles: list[str]) -> dict[str, str]:
    """{profile: how tables and plots name it}: an AI profile by its name, a bot by its class and
    file ("Attack (attack.py)", engine.play.bot.bot_name), or by its whole spec where two bots would
    read the same."""
    from engine.physics.scene import is_bot_spec
    from engine.play.bot import bot_name

    short = {p: bot_name(p) if is_bot_spec(p) else p for p in profiles}
    seen = [short[p] for p in profiles]
    return {p: short[p] if seen.count(short[p]) == 1 else p for p in profiles}


def print_standings(table: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    matrix = table["matrix"]
    profiles = matrix["profiles"]
    name = labels(profiles)
    grid = Table(title="win rate of the row against the column (95 % Wilson interval)")
    grid.add_column("", overflow="fold")
    for p in profiles:
        grid.add_column(name[p], overflow="fold")  # a narrow terminal wraps a name, never cuts it
    for i, p in enumerate(profiles):
        cells = []
        for j in range(len(profiles)):
            rate = matrix["rate"][i][j]
            cells.append("-" if rate is None else f"{rate:.2f} [{matrix['low'][i][j]:.2f}, {matrix['high'][i][j]:.2f}]")
        grid.add_row(name[p], *cells)
    console.print(grid)
    rows = Table(title="profiles")
    for column in ("profile", "Elo [95 %]", "matches", "won", "mean rally shots", "points lost by"):
        rows.add_column(column, overflow="fold")
    for p in profiles:
        rating, row = table["ratings"][p], table["profiles"][p]
        reasons = ", ".join(f"{k} {v}" for k, v in list(row["lost_by"].items())[:4])
        rally = row["mean_rally_shots"]
        rows.add_row(name[p], "-" if rating is None else f"{rating['elo']:.0f} [{rating['low']:.0f}, {rating['high']:.0f}]",
                     str(row["matches"]), str(row["won"]), "-" if rally is None else f"{rally:.2f}", reasons or "-")
    console.print(rows)


def heatmap_png(matrix: dict, path, title: str) -> None:
    """The win-rate matrix as a heatmap, each cell annotated with its rate and interval."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name = labels(matrix["profiles"])
    profiles = [name[p] for p in matrix["profiles"]]
    n = len(profiles)
    rate = np.array([[np.nan if v is None else v for v in row] for row in matrix["rate"]])
    room = 0.09 * max(len(p) for p in profiles)  # inches the longest name takes at the ticks' size
    fig, ax = plt.subplots(figsize=(1.8 * n + 2 + room, 1.5 * n + 1.5 + room / 2))
    image = ax.imshow(rate, vmin=0.0, vmax=1.0, cmap="RdBu")
    for i in range(n):
        for j in range(n):
            if not np.isnan(rate[i, j]):
                ax.text(j, i, f"{rate[i, j]:.2f}\n[{matrix['low'][i][j]:.2f}, {matrix['high'][i][j]:.2f}]",
                        ha="center", va="center", fontsize=9, color="white" if abs(rate[i, j] - 0.5) > 0.3 else "black")
    ax.set_xticks(range(n), profiles, rotation=30, ha="right", rotation_mode="anchor")  # long names side by side
    ax.set_yticks(range(n), profiles)
    ax.set_xlabel("opponent")
    ax.set_ylabel("profile")
    ax.set_title(title, fontsize=9)
    fig.colorbar(image, ax=ax, label="win rate")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def sweep_png(cells: list[dict], path, title: str) -> None:
    """Per sweep cell: end A's win rate (Wilson interval), mean rally shots, realtime factor."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [", ".join(f"{k}={v}" for k, v in cell["cell"].items()) for cell in cells]
    x = np.arange(len(cells))
    fig, axes = plt.subplots(3, 1, figsize=(max(5.0, 1.2 * len(cells) + 2), 7), sharex=True)
    rate = np.array([np.nan if c["end_a"]["rate"] is None else c["end_a"]["rate"] for c in cells])
    low = np.array([np.nan if c["end_a"]["low"] is None else c["end_a"]["low"] for c in cells])
    high = np.array([np.nan if c["end_a"]["high"] is None else c["end_a"]["high"] for c in cells])
    axes[0].errorbar(x, rate, yerr=[rate - low, high - rate], fmt="o", capsize=4)
    axes[0].set_ylim(0, 1)
    axes[0].set_ylabel("end A wins")
    axes[1].plot(x, [c["mean_rally_shots"] or np.nan for c in cells], "o-")
    axes[1].set_ylabel("mean rally shots")
    axes[2].plot(x, [c["realtime_factor"] or np.nan for c in cells], "o-")
    axes[2].set_ylabel("realtime factor")
    axes[2].set_xticks(x, labels, rotation=20, ha="right", fontsize=8)
    axes[0].set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
