"""Watch agents live in Foxglove: a Foxglove WebSocket server (the `foxglove-sdk` package) that streams
what each worker's agent sees, says and does (no rclpy here; the launcher feeds it).

Open the Foxglove app (desktop or https://app.foxglove.dev), "Open connection" -> "Foxglove
WebSocket" -> `ws://localhost:8765` (or the host and `--foxglove PORT` of the run). Per worker k:

| topic | Foxglove schema | what |
|---|---|---|
| /w<k>/camera | foxglove.RawImage (rgb8) | the agent's camera after every reset and action |
| /w<k>/map | foxglove.RawImage (rgb8) | a top-down map of the room: its fixtures, the agent's trail and pose |
| /w<k>/belief | foxglove.RawImage (rgb8) | the map performer's belief map (its own frame, starting heading up), with every action |
| /w<k>/pose | foxglove.PoseInFrame (frame `map`) | the agent's pose (x, y, camera height, yaw) |
| /w<k>/progress | JSON | the task, the step, questions so far, the last action and whether it worked |
| /dialogue | foxglove.Log | every task start, question and answer, and outcome, by worker (name `w<k>`): the Log panel |
| /eval/progress | JSON | episodes finished of all, successes, SR so far |

Every channel is advertised when the view starts, so a client can subscribe before the first episode.
Nothing is recorded here (`--record` writes bags); a client that connects late sees from then on.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Optional, Sequence

import numpy as np

from dialfred_sim.world.rooms import footprint, room_layout

FOXGLOVE_PORT = 8765      # the Foxglove WebSocket port when --foxglove comes without one

MAP_PX_PER_M = 48
MAP_MARGIN = 12


def _timestamp(ns: Optional[int] = None):
    from foxglove.messages import Timestamp  # lazy: foxglove, which the rest of this module does without
    ns = time.time_ns() if ns is None else ns
    return Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)


class RoomMap:
    """A top-down picture of a room (fixtures as filled footprints on the floor) with the agent drawn on it."""

    def __init__(self, scene: str):
        from PIL import Image, ImageDraw  # lazy: PIL, which the rest of this module does without
        layout = room_layout(scene)
        self.width, self.depth = layout.width, layout.depth
        w, h = self.to_px(layout.width, 0.0)[0] + MAP_MARGIN, self.to_px(0.0, 0.0)[1] + MAP_MARGIN
        self.base = Image.new('RGB', (int(w), int(h)), (236, 236, 232))
        draw = ImageDraw.Draw(self.base)
        draw.rectangle([*self.to_px(0.0, layout.depth), *self.to_px(layout.width, 0.0)], fill=(252, 250, 244),
                       outline=(90, 90, 90), width=2)
        for f in layout.fixtures:
            if f.parent is not None:
                continue                                   # stands on another fixture: drawn as that one
            x0, y0, x1, y1 = footprint(f.position, f.yaw, f.spec.size)
            draw.rectangle([*self.to_px(x0, y1), *self.to_px(x1, y0)], fill=(196, 186, 168), outline=(120, 110, 95))
        self.trail: list[tuple[float, float]] = []

    def to_px(self, x: float, y: float) -> tuple[float, float]:
        """World metres (x right, y up) to map pixels (y down)."""
        return MAP_MARGIN + x * MAP_PX_PER_M, MAP_MARGIN + (self.depth - y) * MAP_PX_PER_M

    def draw(self, x: float, y: float, rotation_deg: float) -> np.ndarray:
        from PIL import ImageDraw  # lazy: PIL, which the rest of this module does without
        self.trail.append((x, y))
        img = self.base.copy()
        draw = ImageDraw.Draw(img)
        if len(self.trail) > 1:
            draw.line([self.to_px(*p) for p in self.trail], fill=(70, 130, 200), width=2)
        cx, cy = self.to_px(x, y)
        yaw = math.radians(rotation_deg)
        tip = (cx + 14 * math.cos(yaw), cy - 14 * math.sin(yaw))
        left = (cx + 7 * math.cos(yaw + 2.5), cy - 7 * math.sin(yaw + 2.5))
        right = (cx + 7 * math.cos(yaw - 2.5), cy - 7 * math.sin(yaw - 2.5))
        draw.polygon([tip, left, right], fill=(210, 50, 40))
        return np.asarray(img)


class LiveView:
    """The Foxglove server and its channels; `task`, `frame`, `qa`, `action`, `result` feed it."""

    def __init__(self, workers: int, port: int = FOXGLOVE_PORT, host: str = '127.0.0.1', total: int = 0):
        import foxglove  # lazy: foxglove, which the rest of this module does without
        # lazy: foxglove, which the rest of this module does without
        from foxglove.channels import LogChannel, PoseInFrameChannel, RawImageChannel
        self.context = foxglove.Context()
        self.workers = workers
        self.channels = {}
        for k in range(workers):
            w = f'w{k}'
            self.channels[w] = {
                'camera': RawImageChannel(f'/{w}/camera', context=self.context),
                'map': RawImageChannel(f'/{w}/map', context=self.context),
                'belief': RawImageChannel(f'/{w}/belief', context=self.context),
                'pose': PoseInFrameChannel(f'/{w}/pose', context=self.context),
                'progress': foxglove.Channel(f'/{w}/progress', message_encoding='json', context=self.context,
                                             schema={'type': 'object'}),
            }
        self.dialogue = LogChannel('/dialogue', context=self.context)
        self.progress = foxglove.Channel('/eval/progress', message_encoding='json', context=self.context,
                                         schema={'type': 'object'})
        self.server = foxglove.start_server(name='DialFRED', host=host, port=port, context=self.context)
        self.port = self.server.port
        self.total, self.finished, self.successes = total, 0, 0
        self.state: dict = {}
        self.maps: dict = {}
        self.lock = threading.Lock()

    # ------------------------------------------------------------------ feeding

    def task(self, worker: str, task_id: str, scene: str, instruction: str) -> None:
        with self.lock:
            self.state[worker] = {'task_id': task_id, 'instruction': instruction, 'step': 0, 'questions': 0,
                                  'last_action': '', 'last_action_success': True}
            try:
                self.maps[worker] = RoomMap(scene)
            except Exception:  # noqa: BLE001 - a tasks file of a scene without a layout: no map, the rest works
                self.maps[worker] = None
        self._log(worker, f'{task_id}: "{instruction}"')
        self._progress(worker)

    def frame(self, worker: str, rgb: np.ndarray, pose: Sequence[float], camera_height: float, step: int) -> None:
        # lazy: foxglove, which the rest of this module does without
        from foxglove.messages import Pose, PoseInFrame, Quaternion, RawImage, Vector3
        ch = self.channels[worker]
        stamp = _timestamp()
        rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
        h, w = rgb.shape[:2]
        ch['camera'].log(RawImage(timestamp=stamp, frame_id='agent_camera', width=w, height=h, encoding='rgb8',
                                  step=w * 3, data=rgb.tobytes()))
        x, y, rotation = float(pose[0]), float(pose[1]), float(pose[2])
        yaw = math.radians(rotation)
        ch['pose'].log(PoseInFrame(timestamp=stamp, frame_id='map', pose=Pose(
            position=Vector3(x=x, y=y, z=float(camera_height)),
            orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))))
        room = self.maps.get(worker)
        if room is not None:
            picture = room.draw(x, y, rotation)
            mh, mw = picture.shape[:2]
            ch['map'].log(RawImage(timestamp=stamp, frame_id='map', width=mw, height=mh, encoding='rgb8', step=mw * 3,
                                   data=np.ascontiguousarray(picture).tobytes()))
        with self.lock:
            if worker in self.state:
                self.state[worker]['step'] = int(step)
        self._progress(worker)

    def belief(self, worker: str, picture: np.ndarray) -> None:
        """A picture of the performer's belief map (rgb8), shown on /w<k>/belief."""
        from foxglove.messages import RawImage  # lazy: foxglove, which the rest of this module does without
        picture = np.ascontiguousarray(picture, dtype=np.uint8)
        h, w = picture.shape[:2]
        self.channels[worker]['belief'].log(RawImage(timestamp=_timestamp(), frame_id='belief', width=w, height=h,
                                                     encoding='rgb8', step=w * 3, data=picture.tobytes()))

    def qa(self, worker: str, question_type: str, object_noun: str, answer: str, valid: bool) -> None:
        with self.lock:
            if worker in self.state:
                self.state[worker]['questions'] += 1
        said = answer if valid else '(the oracle could not answer)'
        self._log(worker, f'Q [{question_type}{": " + object_noun if object_noun else ""}] -> {said}')
        self._progress(worker)

    def action(self, worker: str, step: int, name: str, success: bool) -> None:
        with self.lock:
            if worker in self.state:
                self.state[worker].update(step=int(step), last_action=name, last_action_success=bool(success))
        self._progress(worker)

    def result(self, worker: str, task_id: str, success: bool, end_reason: str, steps: int, questions: int) -> None:
        from foxglove.messages import LogLevel  # lazy: foxglove, which the rest of this module does without
        with self.lock:
            self.finished += 1
            self.successes += bool(success)
        outcome = 'success' if success else f'failure ({end_reason})'
        self._log(worker, f'{task_id}: {outcome} after {steps} steps and {questions} questions',
                  LogLevel.Info if success else LogLevel.Warning)
        self.progress.log({'finished': self.finished, 'total': self.total, 'successes': self.successes,
                           'sr': round(100.0 * self.successes / self.finished, 1)})

    def close(self, linger: float = 1.0) -> None:
        """Stop the server, `linger` seconds after the last message (its queue to the clients drains meanwhile)."""
        time.sleep(linger)
        self.server.stop()

    # ------------------------------------------------------------------ helpers

    def _log(self, worker: str, text: str, level=None) -> None:
        from foxglove.messages import Log, LogLevel  # lazy: foxglove, which the rest of this module does without
        self.dialogue.log(Log(timestamp=_timestamp(), level=level or LogLevel.Info, message=text, name=worker))

    def _progress(self, worker: str) -> None:
        with self.lock:
            state = dict(self.state.get(worker, {}))
        self.channels[worker]['progress'].log(state)


def describe(view: LiveView) -> str:
    return (f'Foxglove live view: ws://localhost:{view.port} (Foxglove app -> Open connection -> Foxglove WebSocket); '
            f'topics /w<k>/camera, /w<k>/map, /w<k>/belief, /w<k>/pose, /w<k>/progress, /dialogue, /eval/progress')
