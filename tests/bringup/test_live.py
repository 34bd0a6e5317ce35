"""The Foxglove live view (dialfred_bringup.live), seen by a WebSocket client speaking the Foxglove
WebSocket protocol (the `websockets` package; the payloads decoded by a protobuf wire-format reader
written here, not by the SDK that encoded them; subprotocol foxglove.sdk.v1, the one this server speaks).

Claims: every topic is advertised with its schema as soon as the view starts; a subscriber gets the
camera frame (a foxglove.RawImage with the frame's exact pixels), the top-down map with the agent,
the dialogue as foxglove.Log lines and the progress as JSON, streamed from a recorded episode bag;
during a real `eval --foxglove` through the graph, a client receives camera frames and the QAs.
"""

from __future__ import annotations

import asyncio
import json
import socket
import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest


from dialfred_bringup.live import LiveView, RoomMap
from dialfred_sim.bag import EpisodeRecorder
from dialfred_bringup.replay import replay_bag

REPO = Path(__file__).resolve().parents[2]
TOPICS = {'/w0/camera': 'foxglove.RawImage', '/w0/map': 'foxglove.RawImage', '/w0/belief': 'foxglove.RawImage',
          '/w0/pose': 'foxglove.PoseInFrame',
          '/w0/progress': None, '/dialogue': 'foxglove.Log', '/eval/progress': None}


def varint(buf: bytes, i: int) -> tuple[int, int]:
    shift = value = 0
    while True:
        b = buf[i]
        value |= (b & 0x7F) << shift
        i += 1
        if b < 0x80:
            return value, i
        shift += 7


def protobuf_fields(buf: bytes) -> dict:
    """{field number: [values]} of one protobuf message (varints and fixed32 as int, length-delimited as bytes)."""
    out, i = {}, 0
    while i < len(buf):
        key, i = varint(buf, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = varint(buf, i)
        elif wire == 2:
            n, i = varint(buf, i)
            value, i = bytes(buf[i:i + n]), i + n
        elif wire == 1:
            value, i = buf[i:i + 8], i + 8
        elif wire == 5:
            value, i = int.from_bytes(buf[i:i + 4], 'little'), i + 4     # fixed32 (RawImage's sizes)
        else:
            raise ValueError(f'wire type {wire}')
        out.setdefault(number, []).append(value)
    return out


def raw_image(payload: bytes) -> np.ndarray:
    """foxglove.RawImage: width 2, height 3, encoding 4, step 5, data 6 (foxglove's RawImage.proto)."""
    f = protobuf_fields(payload)
    w, h, enc = f[2][0], f[3][0], f[4][0].decode()
    assert enc == 'rgb8' and f[5][0] == w * 3
    return np.frombuffer(f[6][0], np.uint8).reshape(h, w, 3)


def log_text(payload: bytes) -> tuple[str, str]:
    """foxglove.Log: message 3, name 4."""
    f = protobuf_fields(payload)
    return f[3][0].decode(), f[4][0].decode()


class Client:
    """A Foxglove WebSocket client in a thread: records the advertised channels and every message of
    the topics it subscribes to (as soon as they are advertised)."""

    def __init__(self, port: int, topics: list[str]):
        self.port, self.topics = port, topics
        self.channels: dict = {}
        self.messages: dict = {t: [] for t in topics}
        self.subscribed = threading.Event()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=lambda: asyncio.run(self.run()), daemon=True)
        self.thread.start()

    async def run(self) -> None:
        import websockets
        deadline = time.monotonic() + 120
        while True:
            try:
                ws = await websockets.connect(f'ws://127.0.0.1:{self.port}', subprotocols=['foxglove.sdk.v1'],
                                              max_size=None)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                await asyncio.sleep(0.2)
        by_sub = {}
        async with ws:
            while not self.stop.is_set():
                try:
                    msg = await asyncio.wait_for(ws.recv(), 0.2)
                except asyncio.TimeoutError:
                    continue
                except websockets.exceptions.ConnectionClosed:      # the run ended and closed its server
                    return
                if isinstance(msg, str):
                    data = json.loads(msg)
                    if data['op'] == 'advertise':         # channels may come in several advertisements
                        for c in data['channels']:
                            self.channels[c['topic']] = c
                        new = [t for t in self.topics if t in self.channels and t not in by_sub.values()]
                        subs = [{'id': len(by_sub) + k + 1, 'channelId': self.channels[t]['id']} for k, t in enumerate(new)]
                        by_sub.update({s['id']: t for s, t in zip(subs, new)})
                        if subs:
                            await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subs}))
                        if len(by_sub) == len(self.topics):
                            await asyncio.sleep(0.3)
                            self.subscribed.set()
                else:
                    op, sub, stamp = struct.unpack_from('<BIQ', msg, 0)
                    if op == 1:
                        self.messages[by_sub[sub]].append((stamp, msg[13:]))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def test_a_client_gets_every_topic_and_decodes_a_frame_the_map_a_qa_and_the_progress(tmp_path):
    frames = [np.full((48, 64, 3), 40 * k, np.uint8) for k in range(3)]      # SYNTHETIC frames
    rec = EpisodeRecorder('valid_unseen/000003', 'FloorPlan301', 'valid_unseen', 'Open the drawer.', ['drawer'])
    rec.observation(0, frames[0], (1.0, 1.5, 90.0, 0.0), 0.9)
    rec.question(0, 'location', 'drawer', 'Where is the drawer?', 'The drawer is to your left.', True)
    belief = np.zeros((30, 40, 3), np.uint8)
    belief[:, :20] = (200, 10, 10)                                            # SYNTHETIC belief map
    rec.belief_map(1, belief)
    rec.action(1, 'RotateLeft', -1, -1, True, 1)
    rec.observation(1, frames[1], (1.0, 1.5, 180.0, 0.0), 0.9)
    rec.action(2, 'MoveAhead', -1, -1, True, 1)
    rec.observation(2, frames[2], (0.75, 1.5, 180.0, 0.0), 0.9)
    rec.result(success=False, steps=2, end_reason='stop', questions=1)
    bag = rec.save(tmp_path)
    view = LiveView(1, port=free_port(), total=1)
    client = Client(view.port, ['/w0/camera', '/w0/map', '/w0/belief', '/dialogue', '/w0/progress', '/eval/progress'])
    try:
        assert client.subscribed.wait(30), 'no advertise from the server'
        assert {t: c.get('schemaName') for t, c in client.channels.items() if TOPICS[t]} == \
            {t: s for t, s in TOPICS.items() if s}
        assert all(client.channels[t]['encoding'] == 'json' for t, s in TOPICS.items() if s is None)
        replay_bag(view, bag, speed=20.0)
        deadline = time.monotonic() + 10
        while len(client.messages['/eval/progress']) < 1 and time.monotonic() < deadline:
            time.sleep(0.1)
    finally:
        client.close()
        view.close()
    camera = [raw_image(p) for _, p in client.messages['/w0/camera']]
    assert len(camera) == 3 and all(np.array_equal(a, b) for a, b in zip(camera, frames))
    beliefs = [raw_image(p) for _, p in client.messages['/w0/belief']]
    assert len(beliefs) == 1 and np.array_equal(beliefs[0], belief)
    maps = [raw_image(p) for _, p in client.messages['/w0/map']]
    assert len(maps) == 3 and maps[0].shape[0] > 100
    red = lambda m: np.argwhere((m[..., 0] > 180) & (m[..., 1] < 90))   # the agent's arrow
    assert len(red(maps[0])) and red(maps[2]).mean(0)[1] < red(maps[0]).mean(0)[1]    # it moved to -x: left
    logs = [log_text(p) for _, p in client.messages['/dialogue']]
    assert logs[0] == ('valid_unseen/000003: "Open the drawer."', 'w0')
    assert any('Q [location: drawer] -> The drawer is to your left.' in m for m, _ in logs)
    assert 'failure (stop) after 2 steps' in logs[-1][0]
    progress = [json.loads(p) for _, p in client.messages['/w0/progress']]
    assert progress[-1]['task_id'] == 'valid_unseen/000003' and progress[-1]['questions'] == 1
    assert json.loads(client.messages['/eval/progress'][-1][1]) == {'finished': 1, 'total': 1, 'successes': 0, 'sr': 0.0}


def test_the_room_map_draws_the_agent_where_it_stands():
    room = RoomMap('FloorPlan1')
    a, b = room.draw(1.0, 1.0, 0.0), room.draw(room.width - 1.0, room.depth - 1.0, 90.0)
    red = lambda m: np.argwhere((m[..., 0] > 180) & (m[..., 1] < 90)).mean(0)
    (ya, xa), (yb, xb) = red(a), red(b)
    assert xb > xa and yb < ya                  # to the right (+x) and up the picture (+y)


@pytest.mark.slow   # an evaluation through the graph end to end; fast: the live view's own tests above
def test_eval_through_the_graph_streams_the_camera_and_the_dialogue(tmp_path):
    from dialfred_bringup.evaluation import EvalConfig, run_eval
    from helpers import tiny_checkpoint
    port = free_port()
    client = Client(port, ['/w0/camera', '/dialogue'])
    config = EvalConfig(split='valid_unseen', performer='et', questioner='all', limit=2, workers=1, resolution=64,
                        checkpoint=tiny_checkpoint(tmp_path / 'tiny.pt'), out=tmp_path / 'r.jsonl', foxglove=port)
    try:
        report = run_eval(config, progress=False)
    finally:
        client.close()
    assert client.subscribed.is_set()
    frames = [raw_image(p) for _, p in client.messages['/w0/camera']]
    assert len(frames) >= 2 and frames[0].shape == (64, 64, 3) and frames[0].std() > 0
    logs = [log_text(p)[0] for _, p in client.messages['/dialogue']]
    asked = sum(r.questions for r in report.results)
    assert asked > 0 and sum(m.startswith('Q [') for m in logs) == asked
    assert sum(' after ' in m for m in logs) == 2                           # both outcomes
