"""`pingpong tournament`: many matches as tasks on a local process pool or on Ray, resumable.

Every ordered pair of AI profiles (each at both ends) plays every seed; one match is one task,
`engine.play.match.match_record` in a pool process or a Ray worker. Where the tasks run is an
existing engine's business (concurrent.futures, Ray), not ours: this module submits them, writes
each finished match as one line of DIR/matches.jsonl and shows the progress. A rerun with the
same DIR skips the matches already there, so Ctrl-C loses only the matches still running.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from processes.cli.common import FORMATTER, add_bot_options, bot_budget_s

if TYPE_CHECKING:
    from engine.physics.scene import Scene

# engine.physics.scene.SKILL_NAMES, spelled out: the parser imports no engine (tests/processes/cli/test_cli.py
# checks the two agree).
SKILL_NAMES = ("pro", "club", "novice")

MAX_RETRIES = 3  # Ray re-runs a task whose worker died this many times (Ray's task retries)
WAIT_S = 1.0  # each wait for finished tasks is bounded: the progress bar and Ctrl-C stay live
MATCHES_FILE = "matches.jsonl"
ABANDONED_DIR = "abandoned"  # the records of matches given up, for the task's retry (play)


@dataclass(frozen=True)
class MatchTask:
    """One match to play: the arguments of engine.play.match.match_record, and its record's key."""

    scene: Scene
    seed: int
    a: str
    b: str
    best_of: int | None
    max_ticks: int
    scene_hash: str
    cell: dict = field(default_factory=dict)  # a sweep's overrides, copied into the record
    bots: dict = field(default_factory=dict)  # {spec: source} of its file bots, shipped with the task
    on_bot_error: str = "point"
    bot_budget_s: float | None = None  # None: engine.play.players.DEFAULT_BUDGET_S

    @property
    def key(self) -> tuple:
        return (self.a, self.b, self.seed, self.scene_hash)


def record_key(record: dict) -> tuple:
    """A finished match's key, as MatchTask.key."""
    return (record["a"], record["b"], record["seed"], record["scene_hash"])


def plan(scene: Scene, pairs: list[tuple[str, str]], seeds: int, best_of: int | None, max_ticks: int | None,
         cell: dict | None = None, on_bot_error: str = "point", bot_budget_s: float | None = None) -> list[MatchTask]:
    """The tasks of `pairs` (player at end A, player at end B: AI profiles or bot specs) over
    seeds 0 .. seeds - 1. A file bot's source goes with each task, so a worker on any machine
    plays the bot that was planned (and a changed bot is a new match: its source is in the hash)."""
    from engine.physics.scene import is_bot_spec
    from engine.play.bot import bot_source
    from engine.play.match import match_hash, match_scene

    tasks = []
    for a, b in pairs:
        played = match_scene(scene, a, b, best_of)
        limit = played.ticks if max_ticks is None else max_ticks
        digest = match_hash(played, limit)
        bots = {spec: bot_source(spec) for spec in (a, b) if is_bot_spec(spec) and bot_source(spec) is not None}
        tasks.extend(MatchTask(scene, seed, a, b, best_of, limit, digest, dict(cell or {}), bots, on_bot_error,
                               bot_budget_s) for seed in range(seeds))
    return tasks


def pairs_of(skills: list[str]) -> list[tuple[str, str]]:
    """Every ordered pair of different profiles, so each plays each at both ends; one profile
    plays itself."""
    if len(skills) == 1:
        return [(skills[0], skills[0])]
    return [(a, b) for a in skills for b in skills if a != b]


def play(task: MatchTask, crash_marker: str | None = None, abandon_dir: str | None = None) -> dict:
    """Play one task's match (in a pool process or a Ray worker) and return its record.

    crash_marker: fault injection for the tests: if that file does not exist yet, create it and
    SIGKILL this process, so the first attempt of the task dies as a crashed worker would.
    abandon_dir: where a match given up is recorded (a bot blocked where no interrupt reaches
    it: runtime.watchdog.DecisionWatchdog ends this process): abandoned_path(abandon_dir, task)
    holds its record, as it stood, with the bot named; a task run again finds it there (Ray
    re-runs the task of a worker that ended) and returns it instead of playing the match again.
    """
    from engine.play.bot import register_sources
    from engine.play.match import MatchRecorder
    from engine.play.players import DEFAULT_BUDGET_S
    from processes.runtime.watchdog import DecisionWatchdog

    if crash_marker is not None and not os.path.exists(crash_marker):
        Path(crash_marker).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    given_up = abandoned_path(abandon_dir, task) if abandon_dir is not None else None
    if given_up is not None and given_up.exists():
        return json.loads(given_up.read_text())
    register_sources(task.bots)
    budget = DEFAULT_BUDGET_S if task.bot_budget_s is None else task.bot_budget_s
    recorder = MatchRecorder(task.scene, task.seed, task.a, task.b, task.best_of, task.max_ticks, task.on_bot_error,
                             budget)

    def abandon(reason: str) -> None:
        print(f"pingpong: {reason}", file=sys.stderr, flush=True)
        if given_up is not None:
            record = {**recorder.record(abandoned=reason), **({"cell": task.cell} if task.cell else {})}
            given_up.parent.mkdir(parents=True, exist_ok=True)
            partial = given_up.with_suffix(f".{os.getpid()}.tmp")
            partial.write_text(json.dumps(record))
            os.replace(partial, given_up)

    with DecisionWatchdog(abandon):
        record = recorder.play()
    if task.cell:
        record["cell"] = task.cell
    return record


def abandoned_path(abandon_dir: str, task: MatchTask) -> Path:
    """The file a given-up match's record is written to (play)."""
    import hashlib

    name = hashlib.sha256(json.dumps(list(task.key)).encode()).hexdigest()[:20]
    return Path(abandon_dir) / f"{name}.json"


class MatchLog:
    """DIR/matches.jsonl: one JSON line per finished match, each appended by one write(2) of
    the whole line, then fsync, so a crash leaves whole lines (a cut last line is skipped)."""

    def __init__(self, path: Path):
        self.path = path
        self.records: dict[tuple, dict] = {}
        text = path.read_bytes() if path.exists() else b""
        for line in text.splitlines():
            try:
                record = json.loads(line)
                self.records[record_key(record)] = record
            except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError):
                continue  # the line a crash cut short: that match is played again
        path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        if text and not text.endswith(b"\n"):
            os.write(self._fd, b"\n")  # end the cut line, so the next record starts a line of its own

    def __contains__(self, key: tuple) -> bool:
        return key in self.records

    def append(self, record: dict) -> None:
        line = (json.dumps(record) + "\n").encode()
        os.write(self._fd, line)
        os.fsync(self._fd)
        self.records[record_key(record)] = record

    def close(self) -> None:
        os.close(self._fd)


def _ignore_sigint() -> None:
    """Pool processes leave Ctrl-C to the driver, which decides what stops."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _local_results(tasks: list[MatchTask], workers: int, crash_marker: str | None, abandon_dir: str | None):
    """Finished records, in the order they finish, from a local forkserver process pool.

    A pool process that ends breaks the pool for every task in it: if a match was given up there
    (its record in abandon_dir: play), that record is the match's, and the other unfinished
    tasks go to a new pool; otherwise (a crash) the BrokenProcessPool ends the run."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    # forkserver, as the supervisor: numba's threads make fork() after a kernel has run unsafe.
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["engine.play.match"])
    todo = list(tasks)
    while todo:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_ignore_sigint)
        futures = {pool.submit(play, task, crash_marker, abandon_dir): task for task in todo}
        pending, broken, finished = set(futures), None, False
        try:
            while pending and broken is None:
                done, pending = wait(pending, timeout=WAIT_S, return_when=FIRST_COMPLETED)
                for future in done:
                    try:
                        record = future.result()
                    except BrokenProcessPool as exc:
                        broken = exc
                        continue
                    todo.remove(futures[future])
                    yield record
            finished = broken is None
        finally:
            pool.shutdown(wait=finished, cancel_futures=True)
            if not finished:  # Ctrl-C, an error or a broken pool: end the running matches too
                for process in list((getattr(pool, "_processes", None) or {}).values()):
                    process.terminate()
        if broken is not None:
            given_up = [task for task in todo if abandon_dir and abandoned_path(abandon_dir, task).exists()]
            if not given_up:
                raise broken
            for task in given_up:
                todo.remove(task)
                yield json.loads(abandoned_path(abandon_dir, task).read_text())


def ray_address(cluster: str) -> str | None:
    """`ray` -> None (a local Ray instance); `ray:auto`, `ray:HOST:PORT`, `ray:ray://HOST:PORT` -> the address."""
    if cluster == "ray":
        return None
    if not cluster.startswith("ray:") or cluster == "ray:":
        raise ValueError(f"--cluster: must be local, ray, ray:auto or ray:HOST:PORT; got {cluster!r}")
    return cluster.removeprefix("ray:")


def runtime_env() -> dict:
    """What a Ray cluster's workers need of this project: its source tree as their working
    directory (the packages and the bundled scenes), without the local virtual environment,
    caches and run outputs. Every node's Python must have the dependencies (README: Beyond one
    machine)."""
    root = Path(__file__).resolve().parents[2]
    return {"working_dir": str(root),
            "excludes": [".venv", ".git", ".numba_cache", "__pycache__", "*.egg-info", ".pytest_cache", ".benchmarks",
                         "*.jsonl", "*.png", "*.gif", "*.npz"]}


def _ray_results(tasks: list[MatchTask], cluster: str, workers: int, crash_marker: str | None,
                 abandon_dir: str | None):
    """Finished records, in the order they finish, from Ray tasks (retried if their worker dies)."""
    import ray  # the optional extra pingpong[ray]

    if not ray.is_initialized():
        address = ray_address(cluster)
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, runtime_env=runtime_env(), log_to_driver=False)
    remote_play = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(play)
    pending = [remote_play.remote(task, crash_marker, abandon_dir) for task in tasks]
    finished = False
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1, timeout=WAIT_S)
            if done and pending:  # and every other one finished meanwhile
                more, pending = ray.wait(pending, num_returns=len(pending), timeout=0)
                done += more
            for record in ray.get(done, timeout=WAIT_S * 60):
                yield record
        finished = True
    finally:
        if not finished:
            for ref in pending:
                ray.cancel(ref, force=True)


def results(tasks: list[MatchTask], cluster: str, workers: int, crash_marker: str | None = None,
            abandon_dir: str | None = None):
    """Finished records of `tasks`, in the order they finish, on the local pool or on Ray;
    abandon_dir: where a match given up is recorded (play)."""
    if cluster == "local":
        return _local_results(tasks, workers, crash_marker, abandon_dir)
    return _ray_results(tasks, cluster, workers, crash_marker, abandon_dir)


@dataclass
class RunReport:
    """What a run of tasks did: records of every task finished (now or before), and the pace."""

    records: list[dict]
    planned: int
    skipped: int  # already in matches.jsonl
    played: int  # finished in this run
    wall_seconds: float
    interrupted: bool
    failure: str | None = None  # why the run stopped early: a task raised, or a pool process died

    @property
    def matches_per_minute(self) -> float | None:
        return 60.0 * self.played / self.wall_seconds if self.played and self.wall_seconds > 0 else None


def run_tasks(tasks: list[MatchTask], out: Path, cluster: str, workers: int, show_progress: bool,
              crash_marker: str | None = None) -> RunReport:
    """Play the tasks not yet in out/matches.jsonl, appending each as it finishes.

    Ctrl-C stops the run, and so does a task that fails (a match that raised, a pool process
    that died; Ray re-runs a task whose worker died itself): the matches finished so far stay in
    the file (a rerun resumes), the ones running are dropped.
    """
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                               TimeRemainingColumn)

    log = MatchLog(out / MATCHES_FILE)
    todo = [task for task in tasks if task.key not in log]
    skipped = len(tasks) - len(todo)
    progress = Progress(TextColumn("matches"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[pace]}"),
                        TextColumn("ETA"), TimeRemainingColumn(), TimeElapsedColumn(),
                        console=Console(stderr=True), disable=not show_progress)
    played = 0
    interrupted = False
    failure = None
    started = time.perf_counter()
    try:
        with progress:
            bar = progress.add_task("matches", total=len(tasks), completed=skipped, pace="")
            if todo:
                with closing(results(todo, cluster, workers, crash_marker, str(out / ABANDONED_DIR))) as finished:
                    for record in finished:
                        log.append(record)
                        played += 1
                        minutes = (time.perf_counter() - started) / 60.0
                        progress.update(bar, advance=1, pace=f"{played / minutes:.1f}/min")
    except KeyboardInterrupt:
        interrupted = True
    except Exception as exc:  # noqa: BLE001 - whatever a task raised ends the run, not the finished records
        failure = f"{type(exc).__name__}: {exc}"
    finally:
        log.close()
    wall = time.perf_counter() - started
    records = [log.records[task.key] for task in tasks if task.key in log]
    return RunReport(records, len(tasks), skipped, played, wall, interrupted, failure)


def parse_skills(text: str) -> list[str]:
    """The players of --skills: AI profiles and bots (FILE.py:Class, module:Class), each loaded
    here so that a bad one is told before any match starts."""
    from processes.cli.common import check_players

    skills = [s.strip() for s in text.split(",") if s.strip()]
    unknown = [s for s in skills if s not in SKILL_NAMES and ":" not in s]
    if not skills or unknown or len(set(skills)) != len(skills):
        raise ValueError(f"--skills: a comma-separated list of different players: profiles out of "
                         f"{', '.join(SKILL_NAMES)} or bots (FILE.py:Class); got {text!r}")
    check_players(skills)
    return skills


def check_run_options(args: argparse.Namespace) -> None:
    """Refuse options no run can use, before anything starts."""
    if args.seeds < 1:
        raise ValueError(f"--seeds: must be >= 1, got {args.seeds}")
    if args.workers < 1:
        raise ValueError(f"--workers: must be >= 1, got {args.workers}")
    if args.ticks is not None and args.ticks < 1:
        raise ValueError(f"--ticks: must be >= 1, got {args.ticks}")
    if args.cluster != "local":
        ray_address(args.cluster)
    bot_budget_s(args)


def run_summary(report: RunReport, cluster: str, workers: int) -> dict:
    return {"cluster": cluster, "workers": workers, "matches": len(report.records), "planned": report.planned,
            "skipped": report.skipped, "played": report.played, "wall_seconds": report.wall_seconds,
            "matches_per_minute": report.matches_per_minute, "interrupted": report.interrupted,
            "failure": report.failure}


def tournament_command(args: argparse.Namespace) -> int:
    """Plan, run and summarise a tournament.

    Returns:
        0; 2 for a bad option or scene; 130 after Ctrl-C, 1 after a failed task (the finished
        matches kept either way).
    """
    from engine.physics.scene import SceneError, load_scene
    from processes.cli import standings

    try:
        check_run_options(args)
        skills = parse_skills(args.skills)
        scene = load_scene(args.scene)
        tasks = plan(scene, pairs_of(skills), args.seeds, args.best_of, args.ticks,
                     on_bot_error=args.on_bot_error, bot_budget_s=bot_budget_s(args))
    except (SceneError, ValueError) as exc:
        print(f"pingpong tournament: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    report = run_tasks(tasks, out, args.cluster, args.workers, show_progress=not args.json and sys.stderr.isatty())
    table = standings.standings(report.records, skills)
    summary = {"scene": scene.name, "best_of": args.best_of or scene.match.best_of, "seeds": args.seeds,
               **run_summary(report, args.cluster, args.workers), **table, "out": str(out)}
    (out / "standings.json").write_text(json.dumps(summary, indent=1))
    if table["matrix"]["decided"] and len(skills) > 1:
        standings.heatmap_png(table["matrix"], out / "winrate.png",
                              f"{scene.name}: win rate of the row against the column, {args.seeds} seeds, both ends")
        summary["png"] = str(out / "winrate.png")
    if args.json:
        print(json.dumps(summary))
    else:
        standings.print_standings(table)
        pace = report.matches_per_minute
        print(f"{report.played} matches played, {report.skipped} found in {out / MATCHES_FILE}; "
              f"{pace:.1f} matches/min on {args.cluster}" if pace else
              f"{report.played} matches played, {report.skipped} found in {out / MATCHES_FILE}")
        if "png" in summary:
            print(f"heatmap written to {summary['png']}")
    return stopped("tournament", report, out)


def stopped(command: str, report: RunReport, out: Path) -> int:
    """The exit code of a run; for one that stopped early, what stopped it and what was kept."""
    if not (report.interrupted or report.failure):
        return 0
    why = "stopped" if report.failure is None else f"a task failed ({report.failure})"
    print(f"pingpong {command}: {why}; {len(report.records)} of {report.planned} matches are in "
          f"{out / MATCHES_FILE}, a rerun with the same --out plays the rest", file=sys.stderr)
    return 130 if report.failure is None else 1


def add_run_options(parser: argparse.ArgumentParser, out: str) -> None:
    """The options every many-match command shares: where the tasks run and what they play."""
    parser.add_argument("--seeds", type=int, default=10, help="seeds 0 .. N-1 for every pairing")
    parser.add_argument("--best-of", type=int, default=None, help="games in each match (default: the scene's)")
    parser.add_argument("--ticks", type=int, default=None,
                        help="stop each match after this many ticks even if undecided (default: the scene's duration)")
    parser.add_argument("--cluster", default="local",
                        help="local (a process pool), ray (a local Ray instance), ray:auto or ray:HOST:PORT "
                             "(an existing Ray cluster; README: Beyond one machine)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="processes of the local pool, CPUs of a local Ray instance")
    parser.add_argument("--out", default=out, help="directory of matches.jsonl (a rerun resumes), tables and plots")
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    add_bot_options(parser)


def add_commands(sub) -> None:
    """`pingpong tournament`."""
    parser = sub.add_parser("tournament", help="every pair of AI profiles over many seeds, on a local pool or Ray",
                            formatter_class=FORMATTER)
    parser.add_argument("--skills", default=",".join(SKILL_NAMES),
                        help="comma-separated players to pit: AI profiles and bots (FILE.py:Class)")
    parser.add_argument("--scene", default="match", help="scene TOML file or bundled scene name (needs a referee)")
    add_run_options(parser, out="tournament")
    parser.set_defaults(func=tournament_command)
