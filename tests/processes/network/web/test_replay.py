"""The replay page: a recorded match as one offline file that plays in the browser (processes.network.web.replay)."""
import numpy as np

from processes.network import wire
from processes.network.wire import Kind
from tests.helpers.browser import await_page, errors, get, screenshot


def test_the_replay_page_plays_offline_from_one_file(browser, tmp_path):
    from engine.physics.dtypes import physics_snapshot_dtype
    from engine.play.rules import REASONS, Reason
    from processes.network.web.replay import replay_page

    welcome = wire.encode(Kind.WELCOME, tick=0, slot=wire.Slot.NONE, best_of=1, snapshot_hz=100, heartbeat_ms=500,
                          timeout_ms=5000, dt=0.001, token=bytes(16), scene="match", name_a="Ada", name_b="Bo",
                          feed_port=0, scene_digest=bytes(wire.DIGEST_SIZE))
    record = np.zeros(1, physics_snapshot_dtype(2))[0]
    record["bats"]["quat"] = (1.0, 0.0, 0.0, 0.0)
    record["rally"]["winner"] = -1
    messages = [welcome]
    for i in range(300):  # 3 s of play at 100 snapshots a second
        record["world"]["tick"] = 10 * i
        record["ball"]["pos"] = (-1.2 + 0.008 * i, 0.0, 0.2)
        messages.append(wire.snapshot_from_physics(record, seq=i + 1))
    messages.insert(150, wire.encode(Kind.EVENT, tick=1480, event=wire.EventKind.POINT, winner=1,
                                     reason=REASONS.index(Reason.OUT_LONG), game=0, score=(0, 1), games_won=(0, 0),
                                     shots=3, rally=1))
    page = tmp_path / "replay.html"
    page.write_text(replay_page(messages, "a test"), encoding="utf-8")
    assert "http://" not in page.read_text() and "https://" not in page.read_text()  # nothing to fetch
    browser.get(page.as_uri())
    state = await_page(browser, lambda s: s["events"] == 1 and s["frames"] > 10)
    assert state["lastEvent"]["reason"] == "out_long" and state["lastEvent"]["winner"] == 1
    assert screenshot(browser).std() > 0.05
    assert errors(browser) == [] and state["errors"] == []
