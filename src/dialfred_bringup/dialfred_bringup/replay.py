"""Replay a recorded episode bag (dialfred_sim.bag): its dialogue and actions as text, a captioned GIF and a
contact sheet from the bag alone, or a stream into the live view. A chained episode's bag plays its tasks
one after another (the contact sheet: a row a task).

    ./dialfred replay BAG [--gif OUT.gif] [--sheet OUT.png] [--foxglove [PORT]]
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from dialfred_sim.bag import STEP_NS, BagError, RecordedEpisode, read_bag
from dialfred_sim.dataclass_cli import REQUIRED, arg, parse

from .film import save_captioned_gif, save_contact_sheet
from .live import FOXGLOVE_PORT, LiveView, describe

# --------------------------------------------------------------------------------------------- replay

def transcript(ep: RecordedEpisode) -> list[str]:
    """The episode as lines of text: the task, each QA and action in order, the outcome."""
    lines = [f'{where(ep)}{ep.task["task_id"]} in {ep.task["scene"]}: "{ep.task["instruction"]}"']
    events = [(s, 0, k, f'  Q [{q[1]}{": " + q[2] if q[2] else ""}] -> '
                        f'{q[4] if q[5] else "(the oracle could not answer)"}' + (f' (heard: {q[6]})' if q[6] else ''))
              for k, q in enumerate(ep.dialogue) for s in [q[0]]]
    events += [(a[0] - 1, 1, k, f'{a[0]:>4} {a[1]:<10} {f"({a[2]}, {a[3]})" if a[2] >= 0 else "":<10} '
                                f'{"ok" if a[4] else "failed"}') for k, a in enumerate(ep.actions)]
    lines += [text for *_, text in sorted(events)]
    r = ep.result
    if r:
        lines.append(f'outcome: {"success" if r["success"] else "failure"} ({r["end_reason"]}) after {r["steps"]} '
                     f'steps, {r["questions"]} questions, goal conditions {r["goal_conditions_met"]}/'
                     f'{r["goal_conditions_total"]}' + (f'; {r["error"]}' if r["error"] else ''))
    else:
        lines.append('outcome: not recorded (the episode did not end)')
    return lines


def where(ep: RecordedEpisode) -> str:
    """'task k of n: ' for a task of a chained episode's bag, '' for a bag of one task."""
    return f'task {ep.place} of {ep.of}: ' if ep.of > 1 else ''


def bag_film(parts: list) -> list:
    """The captioned GIF's frames of a bag: its tasks' films one after another (read_bag's parts)."""
    return [shot for ep in parts for shot in film(ep)]


def beside(frame, picture):
    """The frame with `picture` (a performer's map) fitted into a square of the frame's height on its right."""
    from PIL import Image  # lazy: PIL, which the rest of this module does without
    h = frame.shape[0]
    scale = h / max(picture.shape[:2])
    size = (max(1, round(picture.shape[1] * scale)), max(1, round(picture.shape[0] * scale)))
    box = Image.new('RGB', (h, h), (255, 255, 255))
    box.paste(Image.fromarray(picture).resize(size, Image.BILINEAR), ((h - size[0]) // 2, (h - size[1]) // 2))
    return np.concatenate([frame, np.asarray(box)], axis=1)


def film(ep: RecordedEpisode) -> list:
    """(frame, caption lines) pairs for a captioned GIF: the start, each QA over the frame it was asked
    on, each action over the frame after it; with the performer's map beside each frame where the bag
    holds one (the map it decided its next action on)."""
    title = f'{where(ep)}{ep.task["task_id"]}: "{ep.task["instruction"]}"'
    maps = sorted(ep.maps, key=lambda m: m[0])

    def shot(step: int):
        frame = ep.frame(step)
        if not maps:
            return frame
        made = [m for m in maps if m[0] <= step + 1] or maps[:1]     # decided on frames up to this one
        return beside(frame, made[-1][1])

    out = [(shot(0), [title, 'start'])]
    qas = sorted(ep.dialogue, key=lambda q: q[0])
    qi = 0
    for a in ep.actions:
        while qi < len(qas) and qas[qi][0] < a[0]:
            q = qas[qi]
            out.append((shot(q[0]), [title, f'Q [{q[1]}{": " + q[2] if q[2] else ""}]',
                                     f'A: {q[4] if q[5] else "(no answer)"}'] + ([f'heard: {q[6]}'] if q[6] else [])))
            qi += 1
        target = f' at ({a[2]}, {a[3]})' if a[2] >= 0 else ''
        out.append((shot(a[0]), [title, f'{a[0]}: {a[1]}{target} {"ok" if a[4] else "failed"}']))
    if ep.result:
        out[-1][1].append('success' if ep.result['success'] else f'failure ({ep.result["end_reason"]})')
    return out


def replay_bag(view, path, worker: str = 'w0', speed: float = 1.0) -> None:
    """Stream a recorded bag into a live view (dialfred_bringup.live.LiveView) at `speed` times the simulator's
    clock (0.1 s a step); a chained episode's tasks one after another."""
    start = time.monotonic()
    for ep in read_bag(path):
        t = ep.task
        view.task(worker, t['task_id'], t['scene'], t['instruction'])
        events = [(time_ns, 0, ('frame', step, rgb)) for time_ns, step, rgb in ep.frames]
        events += [(q[0] * STEP_NS + 1, 1, ('qa', q)) for q in ep.dialogue]
        events += [(a[0] * STEP_NS, 2, ('action', a)) for a in ep.actions]
        events += [((step - 1) * STEP_NS + 1, 3, ('belief', picture)) for step, picture in ep.maps]
        poses = {p[0]: p for p in ep.poses}
        for time_ns, _, event in sorted(events, key=lambda e: (e[0], e[1])):
            wait = start + (ep.offset_ns + time_ns) / 1e9 / max(speed, 1e-6) - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            if event[0] == 'frame':
                p = poses.get(event[1], (event[1], 0.0, 0.0, 0.0, 0.0))
                view.frame(worker, event[2], (p[1], p[2], p[3], p[4]), 0.9, event[1])
            elif event[0] == 'qa':
                q = event[1]
                view.qa(worker, q[1], q[2], q[4], q[5])
            elif event[0] == 'belief':
                view.belief(worker, event[1])
            else:
                a = event[1]
                view.action(worker, a[0], a[1], a[4])
        if ep.result:
            r = ep.result
            view.result(worker, t['task_id'], r['success'], r['end_reason'], r['steps'], r['questions'])


@dataclass
class ReplayConfig:
    """Print an episode bag's dialogue and actions and render it as a captioned GIF and a contact sheet
    (no simulator)."""

    bag: Path = arg(REQUIRED, 'a bag folder written with --record (or its .mcap file)', positional=True)
    gif: Optional[Path] = arg(None, 'the captioned GIF (none: <bag>.gif beside the bag)', metavar='PATH')
    sheet: Optional[Path] = arg(None, 'the contact sheet PNG (none: <bag>_sheet.png beside the bag)', metavar='PATH')
    pictures: bool = arg(True, 'write the GIF and the contact sheet (--no-pictures: only print the transcript)')
    foxglove: Optional[int] = arg(None, 'also stream the episode to the Foxglove app (a Foxglove WebSocket server on '
                                  f'PORT; the flag alone: {FOXGLOVE_PORT}) at --speed times the simulator clock, then '
                                  'keep serving until Ctrl-C', const=FOXGLOVE_PORT, metavar='PORT')
    speed: float = arg(1.0, 'replay speed for --foxglove (1 = 10 steps/s)')


def main(argv=None) -> int:
    args = parse(ReplayConfig, argv, prog='dialfred replay', description=' '.join(ReplayConfig.__doc__.split()))
    try:
        parts = read_bag(args.bag)
    except BagError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    ep = parts[0]
    if len(parts) > 1:
        print(f'{ep.path.name}: a chained episode of {len(parts)} tasks, played one after another\n')
    print('\n\n'.join('\n'.join(transcript(part)) for part in parts))
    if not any(part.frames for part in parts):
        print('(no camera frames in this bag: no pictures)', file=sys.stderr)
        return 0
    gif = args.gif or ep.path.parent / f'{ep.path.name}.gif'
    sheet = args.sheet or ep.path.parent / f'{ep.path.name}_sheet.png'
    if args.pictures:
        save_captioned_gif(bag_film(parts), gif)
        print(f'GIF: {gif}')
        save_contact_sheet([(where(part) + part.task['task_id'], [f[2] for f in part.frames]) for part in parts
                            if part.frames], sheet)
        print(f'contact sheet: {sheet}')
    if args.foxglove is not None:
        view = LiveView(1, port=args.foxglove, total=1)
        print(describe(view), flush=True)
        try:
            input('connect Foxglove, then press Enter to stream the episode (Ctrl-C to quit) ')
            while True:
                replay_bag(view, ep.path, speed=args.speed)
                input('streamed; Enter streams it again, Ctrl-C quits ')
        except (KeyboardInterrupt, EOFError):
            pass
        finally:
            view.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
