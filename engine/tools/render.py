"""Pictures of a replay: side view (x-z) and top view (x-y), as a PNG, an RGB array or an animated GIF."""
from __future__ import annotations

import numpy as np

from engine.physics import equipment
from engine.physics.geometry import Body

HALF_L, HALF_W = equipment.TABLE_LENGTH / 2, equipment.TABLE_WIDTH / 2


def _figure():
    import matplotlib

    matplotlib.use("Agg")  # files only: no display is needed or wanted
    import matplotlib.pyplot as plt

    fig, (side, top) = plt.subplots(2, 1, figsize=(9, 7), gridspec_kw={"height_ratios": [1, 1.2]})
    side.set_title("side view")
    side.add_patch(plt.Rectangle((-HALF_L, -equipment.TABLE_THICKNESS), equipment.TABLE_LENGTH,
                                 equipment.TABLE_THICKNESS, color="#1f5f8b"))
    side.plot([0, 0], [0, equipment.NET_HEIGHT], color="k", lw=2)
    side.set_xlim(-3.2, 3.2)
    side.set_ylim(-0.1, 1.0)
    side.set_xlabel("x (m)")
    side.set_ylabel("z (m)")
    side.set_aspect("equal")
    top.set_title("top view")
    top.add_patch(plt.Rectangle((-HALF_L, -HALF_W), equipment.TABLE_LENGTH, equipment.TABLE_WIDTH,
                                color="#1f5f8b"))
    top.plot([0, 0], [-equipment.NET_HALF_WIDTH, equipment.NET_HALF_WIDTH], color="k", lw=2)
    top.plot([-HALF_L, HALF_L], [0, 0], color="w", lw=0.8)
    top.set_xlim(-3.2, 3.2)
    top.set_ylim(-1.3, 1.3)
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_aspect("equal")
    fig.tight_layout()
    return fig, side, top, plt


def png(frames: np.ndarray, events: np.ndarray, path: str, title: str, seconds: float = 3.0) -> None:
    """The ball's path over the last `seconds` of the replay, bats where they ended, impacts marked."""
    fig, plt = _picture(frames, events, title, seconds)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def rgb(frames: np.ndarray, events: np.ndarray, title: str, seconds: float = 3.0) -> np.ndarray:
    """png's picture as a (700, 900, 3) uint8 array (rows, columns, RGB) at 100 dpi."""
    fig, plt = _picture(frames, events, title, seconds)
    fig.set_dpi(100)
    fig.canvas.draw()
    pixels = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return pixels


def _picture(frames: np.ndarray, events: np.ndarray, title: str, seconds: float):
    """The figure of png and rgb: (figure, pyplot)."""
    fig, side, top, plt = _figure()
    if len(frames):
        t = frames["world"]["time"]
        keep = frames[t >= t[-1] - seconds]
        pos = keep["ball"]["pos"]
        side.plot(pos[:, 0], pos[:, 2], color="orange", lw=1.2)
        top.plot(pos[:, 0], pos[:, 1], color="orange", lw=1.2)
        for bat in keep["bats"][-1]:
            side.plot(bat["pos"][0], bat["pos"][2], "s", color="crimson", ms=8)
            top.plot(bat["pos"][0], bat["pos"][1], "s", color="crimson", ms=8)
        recent = events[events["time"] >= t[-1] - seconds] if len(events) else events
        for ev in recent:
            marker = "x" if int(ev["body"]) in (Body.TABLE, Body.FLOOR) else "o"
            side.plot(ev["pos"][0], ev["pos"][2], marker, color="k", ms=5)
            top.plot(ev["pos"][0], ev["pos"][1], marker, color="k", ms=5)
    fig.suptitle(title)
    return fig, plt


def gif(frames: np.ndarray, path: str, title: str, seconds: float = 4.0, fps: int = 25) -> None:
    """An animation of the last `seconds` of the replay (a ball with a short trail, the bats)."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    fig, side, top, plt = _figure()
    if not len(frames):
        fig.savefig(path)
        plt.close(fig)
        return
    t = frames["world"]["time"]
    frame_dt = float(t[1] - t[0]) if len(t) > 1 else 0.01
    stride = max(1, int(round(1.0 / (fps * frame_dt))))
    shown = frames[t >= t[-1] - seconds][::stride]
    ball_side, = side.plot([], [], "o", color="orange", ms=6)
    ball_top, = top.plot([], [], "o", color="orange", ms=6)
    trail_side, = side.plot([], [], color="orange", lw=0.8, alpha=0.6)
    trail_top, = top.plot([], [], color="orange", lw=0.8, alpha=0.6)
    bats_side, = side.plot([], [], "s", color="crimson", ms=8)
    bats_top, = top.plot([], [], "s", color="crimson", ms=8)
    fig.suptitle(title)

    def draw(k):
        p = shown["ball"]["pos"][: k + 1]
        ball_side.set_data([p[-1, 0]], [p[-1, 2]])
        ball_top.set_data([p[-1, 0]], [p[-1, 1]])
        trail_side.set_data(p[-12:, 0], p[-12:, 2])
        trail_top.set_data(p[-12:, 0], p[-12:, 1])
        bats = shown["bats"][k]["pos"]
        bats_side.set_data(bats[:, 0], bats[:, 2])
        bats_top.set_data(bats[:, 0], bats[:, 1])
        return ball_side, ball_top, trail_side, trail_top, bats_side, bats_top

    FuncAnimation(fig, draw, frames=len(shown), blit=True).save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)
