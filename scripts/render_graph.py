#!/usr/bin/env python3
"""Draw the DialFRED ROS 2 node graph of one worker for the README.

The four nodes (simulator, oracle, questioner, performer) and the launcher's client node, with every
service (solid arrow, client -> server), the RunTask action (thick arrow) and every topic (dashed
arrow, publisher -> subscriber) that the nodes create; the numbers follow one episode. All names are
relative: worker k runs them in namespace /w<k>. One layout (the tables below) gives both pictures:
docs/images/graph.png (Pillow, drawn at 2x and scaled down; the same bytes every run) and
docs/images/graph.svg (written by hand).

    ./dialfred env python scripts/render_graph.py
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / 'docs' / 'images'
W, H = 900, 810          # the picture, in SVG units (= PNG pixels)
SCALE = 2                # the PNG is drawn this much larger, then scaled down

# name: (x0, y0, x1, y1), title, lines under it
NODES = {
    'client': ((290, 84, 610, 150), 'launcher client',
               ['node dialfred_launcher (launch.py eval / demo)', 'PerformerWorker, workers.py']),
    'performer': ((340, 280, 560, 336), 'performer', ['node dialfred_performer']),
    'questioner': ((30, 460, 230, 516), 'questioner', ['node dialfred_questioner']),
    'oracle': ((650, 460, 870, 516), 'oracle', ['node dialfred_oracle', '(+ dialfred_oracle_sim_client)']),
    'simulator': ((300, 680, 600, 736), 'simulator', ['node dialfred_sim (pybullet)']),
}

# kind, name, type, from, to, path (the last point is the arrow's tip), label (x, y, anchor), step, note.
# A label is its step's number, the name, the type and the note, one line each, from its first baseline.
EDGES = [
    # workers.py PerformerWorker: ActionClient(graph.client_node, RunTask, '<ns>/performer/run_task');
    # performer/node.py: ActionServer(self, RunTask, 'performer/run_task')
    ('action', 'performer/run_task', 'dialfred_msgs/action/RunTask', 'client', 'performer',
     [(480, 150), (480, 280)], (494, 196, 'start'), 1, 'goal (task id, seed) ↓, feedback and result ↑'),
    # performer/node.py: create_publisher(QAPair, 'dialogue/qa'); subscribers: demo.py, evaluation.py (--foxglove)
    ('topic', 'dialogue/qa', 'dialfred_msgs/msg/QAPair', 'performer', 'client',
     [(420, 280), (420, 150)], (408, 196, 'end'), None, 'each question and answer'),
    # sim/node.py: create_publisher(Observation, 'sim/observation'); subscribers: demo.py, evaluation.py (--foxglove)
    ('topic', 'sim/observation', 'dialfred_msgs/msg/Observation', 'simulator', 'client',
     [(600, 722), (884, 722), (884, 120), (610, 120)], (747, 94, 'middle'), None, None),
    # performer/node.py: create_client(SimReset, 'sim/reset'); sim/node.py: create_service(SimReset, 'sim/reset')
    ('service', 'sim/reset', 'dialfred_msgs/srv/SimReset', 'performer', 'simulator',
     [(420, 336), (420, 680)], (408, 412, 'end'), 2, 'reply: task, first frame'),
    # performer/node.py: create_client(QuestionerAsk, 'questioner/ask'); questioner/node.py: create_service(...)
    ('service', 'questioner/ask', 'dialfred_msgs/srv/QuestionerAsk', 'performer', 'questioner',
     [(340, 298), (130, 298), (130, 460)], (328, 250, 'end'), 3, 'frame, dialogue → question'),
    # performer/node.py: create_client(OracleAnswer, 'oracle/answer'); oracle/node.py: create_service(...)
    ('service', 'oracle/answer', 'dialfred_msgs/srv/OracleAnswer', 'performer', 'oracle',
     [(560, 298), (800, 298), (800, 460)], (572, 250, 'start'), 4, 'question → answer'),
    # oracle/node.py: sim_side.create_client(GroundTruth, 'sim/ground_truth'); sim/node.py: create_service(...)
    ('service', 'sim/ground_truth', 'dialfred_msgs/srv/GroundTruth', 'oracle', 'simulator',
     [(760, 516), (760, 698), (600, 698)], (748, 566, 'end'), 5, 'the world, for the answer'),
    # performer/node.py: create_client(SimStep, 'sim/step'); sim/node.py: create_service(SimStep, 'sim/step')
    ('service', 'sim/step', 'dialfred_msgs/srv/SimStep', 'performer', 'simulator',
     [(480, 336), (480, 680)], (494, 412, 'start'), 6, 'action → next frame'),
    # questioner/node.py: create_publisher(QAPair, 'questioner/question'); no create_subscription for it
    ('topic', 'questioner/question', 'dialfred_msgs/msg/QAPair', 'questioner', None,
     [(130, 516), (130, 596)], (142, 556, 'start'), None, 'no subscriber in the project'),
    # performer/node.py: create_publisher(Action, 'performer/action'); no create_subscription for it
    ('topic', 'performer/action', 'dialfred_msgs/msg/Action', 'performer', None,
     [(560, 322), (630, 322)], (572, 346, 'start'), None, 'no subscriber in the project'),
]

COLOURS = {'service': (31, 95, 168), 'action': (192, 57, 43), 'topic': (30, 130, 76)}
WIDTHS = {'service': 2.0, 'action': 5.0, 'topic': 2.0}
HEAD = {'service': (11, 4.5), 'action': (16, 8), 'topic': (11, 4.5)}   # arrowhead length, half width
DASH = (7, 5)
NODE_FILL, NODE_EDGE, INK, GREY = (244, 246, 250), (70, 80, 95), (25, 28, 34), (95, 100, 110)
TITLE = "DialFRED node graph (one worker's namespace)"
SUBTITLE = 'All names are relative: worker k runs them in namespace /w<k> (e.g. /w0/sim/step).'
LEGEND_Y = 760          # the legend's line
LEGEND_ITEMS = [('service', 30, 'service: client → server'),
                ('action', 300, 'action: goal → server (feedback, result back)'),
                ('topic', 640, 'topic: publisher → subscriber')]     # kind, x, text
FLOW = ["One episode: 1 goal, 2 reset, then before each action 3 ask the questioner, 4 ask the oracle what it "
        "asks (5 the oracle reads", "the simulator's ground truth), 6 step. Steps 3-5 only with the performer's "
        "questioner parameter on."]
# text styles: font file, size, colour
STYLES = {'title': ('DejaVuSans-Bold.ttf', 20, INK), 'sub': ('DejaVuSans.ttf', 12, GREY),
          'node': ('DejaVuSans-Bold.ttf', 15, INK), 'nodeline': ('DejaVuSans.ttf', 11, GREY),
          'name': ('DejaVuSans-Bold.ttf', 12.5, None), 'type': ('DejaVuSans.ttf', 11, INK),
          'note': ('DejaVuSans-Oblique.ttf', 11, GREY), 'legend': ('DejaVuSans.ttf', 11.5, INK),
          'num': ('DejaVuSans-Bold.ttf', 10.5, (255, 255, 255))}
LINE_GAP = {'name': 15, 'type': 14, 'note': 14}


def label_lines(name, typ, note):
    """(style, text) lines of an edge's label."""
    return [(s, t) for s, t in (('name', name), ('type', typ), ('note', note)) if t]


def shortened(path, length):
    """The path with its last segment cut short by `length` (where the arrowhead starts)."""
    (x0, y0), (x1, y1) = path[-2], path[-1]
    d = ((x1 - x0) ** 2 + (y1 - y0) ** 2) ** 0.5
    return path[:-1] + [(x1 - (x1 - x0) * length / d, y1 - (y1 - y0) * length / d)]


def head_polygon(path, length, half):
    (x0, y0), (x1, y1) = path[-2], path[-1]
    d = ((x1 - x0) ** 2 + (y1 - y0) ** 2) ** 0.5
    ux, uy = (x1 - x0) / d, (y1 - y0) / d
    bx, by = x1 - ux * length, y1 - uy * length
    return [(x1, y1), (bx - uy * half, by + ux * half), (bx + uy * half, by - ux * half)]


def dashes(path, on, off):
    """The dashes of a dashed polyline, as segments, the pattern running on across corners."""
    out, phase = [], 0.0
    for (x0, y0), (x1, y1) in zip(path, path[1:]):
        d = ((x1 - x0) ** 2 + (y1 - y0) ** 2) ** 0.5
        t = 0.0
        while t < d:
            pos = phase % (on + off)
            step = min((on - pos) if pos < on else (on + off - pos), d - t)
            if pos < on:
                a, b = t / d, (t + step) / d
                out.append([(x0 + (x1 - x0) * a, y0 + (y1 - y0) * a), (x0 + (x1 - x0) * b, y0 + (y1 - y0) * b)])
            t += step
            phase += step
    return out


def texts():
    """Every text of the picture: (x, y baseline, anchor start|middle|end, style, text, colour)."""
    out = [(W / 2, 32, 'middle', 'title', TITLE, None), (W / 2, 52, 'middle', 'sub', SUBTITLE, None)]
    for (x0, y0, x1, y1), title, lines in NODES.values():
        cx, y = (x0 + x1) / 2, (y0 + y1) / 2 - 7 * len(lines) + 6
        out.append((cx, y, 'middle', 'node', title, None))
        for k, line in enumerate(lines):
            out.append((cx, y + 16 + 14 * k, 'middle', 'nodeline', line, None))
    for kind, name, typ, _, _, _, (x, y, anchor), step, note in EDGES:
        for style, text in label_lines(name, typ, note):
            shift = {'start': 20, 'end': -20}.get(anchor, 0) if step and style == 'name' else 0
            out.append((x + shift, y, anchor, style, text, COLOURS[kind] if style == 'name' else None))
            y += LINE_GAP[style]
    out += [(x + 60, LEGEND_Y + 4, 'start', 'legend', text, None) for _, x, text in LEGEND_ITEMS]
    return out + [(W / 2, LEGEND_Y + 26 + 14 * k, 'middle', 'note', line, None) for k, line in enumerate(FLOW)]


def badges():
    """(cx, cy, number) of each step's badge, beside its name on the arrow's side."""
    out = []
    for _, _, _, _, _, _, (x, y, anchor), step, _ in EDGES:
        if step:
            out.append((x + 8 if anchor == 'start' else x - 8, y - 4.5, step))
    return out


def arrows():
    """(kind, path) of every edge, legend samples included."""
    return [(e[0], e[5]) for e in EDGES] + [(k, [(x, LEGEND_Y), (x + 50, LEGEND_Y)]) for k, x, _ in LEGEND_ITEMS]


# ---------------------------------------------------------------------------------------------- PNG


def font(style, scale):
    file, size, _ = STYLES[style]
    path = Path('/usr/share/fonts/truetype/dejavu') / file
    return ImageFont.truetype(str(path), size * scale) if path.exists() else ImageFont.load_default(size=size * scale)


def render_png(path: Path) -> None:
    s = SCALE
    img = Image.new('RGB', (W * s, H * s), (255, 255, 255))
    d = ImageDraw.Draw(img)
    P = lambda pts: [(x * s, y * s) for x, y in pts]
    for (x0, y0, x1, y1), _, _ in NODES.values():
        d.rounded_rectangle((x0 * s, y0 * s, x1 * s, y1 * s), radius=8 * s, fill=NODE_FILL, outline=NODE_EDGE,
                            width=int(1.5 * s))
    for kind, pts in arrows():
        colour, width = COLOURS[kind], round(WIDTHS[kind] * s)
        line = shortened(pts, HEAD[kind][0] - 1)
        if kind == 'topic':
            for seg in dashes(line, *DASH):
                d.line(P(seg), fill=colour, width=width)
        else:
            d.line(P(line), fill=colour, width=width, joint='curve')
        d.polygon(P(head_polygon(pts, *HEAD[kind])), fill=colour)
    for cx, cy, n in badges():
        d.ellipse(((cx - 8) * s, (cy - 8) * s, (cx + 8) * s, (cy + 8) * s), fill=INK)
        d.text((cx * s, cy * s), str(n), font=font('num', s), fill=STYLES['num'][2], anchor='mm')
    for x, y, anchor, style, text, colour in texts():
        d.text((x * s, y * s), text, font=font(style, s), fill=colour or STYLES[style][2],
               anchor={'start': 'ls', 'middle': 'ms', 'end': 'rs'}[anchor], stroke_width=2 * s,
               stroke_fill=(255, 255, 255))
    small = img.resize((W, H), Image.LANCZOS)   # 128 colours: a quarter of the bytes, looks the same
    small.quantize(colors=128, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE).save(path, optimize=True)


# ---------------------------------------------------------------------------------------------- SVG


def hexc(rgb):
    return '#%02x%02x%02x' % rgb


def esc(text):
    return text.replace('&', '&amp;').replace('<', '&lt;').replace('>', '&gt;')


def pts(path):
    return ' '.join(f'{x:g},{y:g}' for x, y in path)


def render_svg(path: Path) -> None:
    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" '
         'font-family="DejaVu Sans, Verdana, sans-serif">', '<defs>']
    for kind, (length, half) in HEAD.items():      # base of the head at the path's end: refX 0
        o.append(f'<marker id="head-{kind}" markerUnits="userSpaceOnUse" markerWidth="{length}" '
                 f'markerHeight="{2 * half}" refX="0" refY="{half}" orient="auto">'
                 f'<path d="M0,0 L{length},{half} L0,{2 * half} z" fill="{hexc(COLOURS[kind])}"/></marker>')
    o += ['</defs>', f'<rect width="{W}" height="{H}" fill="#ffffff"/>']
    for (x0, y0, x1, y1), _, _ in NODES.values():
        o.append(f'<rect x="{x0}" y="{y0}" width="{x1 - x0}" height="{y1 - y0}" rx="8" fill="{hexc(NODE_FILL)}" '
                 f'stroke="{hexc(NODE_EDGE)}" stroke-width="1.5"/>')
    for kind, p in arrows():
        dash = f' stroke-dasharray="{DASH[0]},{DASH[1]}"' if kind == 'topic' else ''
        o.append(f'<polyline points="{pts(shortened(p, HEAD[kind][0]))}" fill="none" stroke="{hexc(COLOURS[kind])}" '
                 f'stroke-width="{WIDTHS[kind]:g}" stroke-linejoin="round"{dash} marker-end="url(#head-{kind})"/>')
    for cx, cy, n in badges():
        o.append(f'<circle cx="{cx:g}" cy="{cy:g}" r="8" fill="{hexc(INK)}"/>'
                 f'<text x="{cx:g}" y="{cy + 3.8:g}" text-anchor="middle" font-size="{STYLES["num"][1]}" '
                 f'font-weight="bold" fill="#ffffff">{n}</text>')
    for x, y, anchor, style, text, colour in texts():
        file, size, default = STYLES[style]
        weight = ' font-weight="bold"' if 'Bold' in file else ''
        italic = ' font-style="italic"' if 'Oblique' in file else ''
        o.append(f'<text x="{x:g}" y="{y:g}" text-anchor="{anchor}" font-size="{size:g}"{weight}{italic} '
                 f'fill="{hexc(colour or default)}" stroke="#ffffff" stroke-width="4" paint-order="stroke">'
                 f'{esc(text)}</text>')
    o.append('</svg>')
    path.write_text('\n'.join(o) + '\n')


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    render_png(OUT / 'graph.png')
    render_svg(OUT / 'graph.svg')
    print(f'wrote {OUT / "graph.png"} and {OUT / "graph.svg"}')


if __name__ == '__main__':
    main()
