"""`./dialfred graph`: the running ROS graph in this ROS domain, as `ros2 node list`, `ros2 topic list -t`,
`ros2 service list -t` and `ros2 action list` would show it (there is no `ros2` CLI on PyPI).

Discovery takes a moment: the graph is read once it has changed nothing for 1.5 s, after at least `--wait`
seconds (default 1) and at most 20. Actions appear as their hidden services and topics
(`<name>/_action/...`) and are listed once, by name. ROS's own topics and every node's parameter services
are left out unless `--all`. A name two nodes share is flagged: ROS cannot tell them apart. `--json` prints
one JSON object instead of the four lists.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import rclpy

from dialfred_sim.dataclass_cli import Parser

ACTION_MARK = '/_action/'
SETTLE_S = 1.5       # the graph is read once discovery has changed nothing for this long ...
LIMIT_S = 20.0       # ... or after this long in all


def snapshot(node) -> dict:
    """What `node` sees of the graph now: node names (with repeats), topics and services with their types."""
    return {'names': sorted(f'{ns.rstrip("/")}/{name}' for name, ns in node.get_node_names_and_namespaces()),
            'topics': dict(node.get_topic_names_and_types()), 'services': dict(node.get_service_names_and_types())}


def read_graph(node, wait_s: float, settle_s: float = SETTLE_S, limit_s: float = LIMIT_S,
               everything: bool = False) -> dict:
    """{'nodes', 'topics', 'services', 'actions', 'duplicates', 'settled'} of the graph `node` sees: after at
    least `wait_s` seconds, once nothing has changed for `settle_s` seconds (at most `limit_s` in all;
    'settled' False if it was still changing). `everything`: also ROS's own topics (/rosout,
    /parameter_events) and every node's parameter services, as `ros2 topic list` and `ros2 service list` show."""
    start = time.monotonic()
    seen, since = None, start
    while True:
        rclpy.spin_once(node, timeout_sec=0.1)
        now_seen, now = snapshot(node), time.monotonic()
        if now_seen != seen:
            seen, since = now_seen, now
        settled = now - since >= settle_s
        if (now - start >= wait_s and settled) or now - start >= limit_s:
            break
    me = node.get_fully_qualified_name()
    names = [n for n in seen['names'] if n != me]
    topics, services = seen['topics'], seen['services']
    actions = sorted({name.split(ACTION_MARK)[0] for name in (*topics, *services) if ACTION_MARK in name})
    own = (f'{me}/', '/rosout', '/parameter_events')     # this reader's own endpoints and ROS's own topics

    def keep(name: str) -> bool:
        if ACTION_MARK in name or name.startswith(own[0]):
            return False
        return everything or name not in own[1:]

    return {'nodes': sorted(set(names)),
            'duplicates': sorted({n for n in names if names.count(n) > 1}),
            'topics': {n: t for n, t in sorted(topics.items()) if keep(n)},
            'services': {n: t for n, t in sorted(services.items())
                         if keep(n) and (everything or not _parameter_service(n))},
            'actions': actions, 'settled': settled}


def _parameter_service(name: str) -> bool:
    """Every node's own parameter services (`ros2 service list` shows them; they say nothing of the graph)."""
    return name.rsplit('/', 1)[-1] in ('describe_parameters', 'get_parameter_types', 'get_parameters',
                                       'get_type_description', 'list_parameters', 'set_parameters',
                                       'set_parameters_atomically')


def main(argv=None) -> int:
    ap = Parser(prog='./dialfred graph', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--wait', type=float, default=1.0, help='seconds of discovery at least; the graph is then read once '
                    f'it has not changed for {SETTLE_S:g} s (at most {LIMIT_S:g} s in all, or --wait) (default 1)')
    ap.add_argument('--all', action='store_true', help="also ROS's own topics (/rosout, /parameter_events) and every "
                    "node's parameter services, as ros2 topic list and ros2 service list show them")
    ap.add_argument('--json', action='store_true', help='one JSON object instead of the lists')
    args = ap.parse_args(argv)
    if not 0 <= args.wait <= 600:
        ap.error(f'--wait must be 0 to 600 seconds, got {args.wait}')
    rclpy.init()
    try:
        node = rclpy.create_node('dialfred_graph_reader', start_parameter_services=False, enable_rosout=False)
        graph = read_graph(node, args.wait, limit_s=max(LIMIT_S, args.wait), everything=args.all)
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
    if args.json:
        print(json.dumps(graph, indent=1))
        return 0
    for title in ('nodes', 'topics', 'services', 'actions'):
        entries = graph[title]
        print(f'{title} ({len(entries)}):')
        for name in entries:
            types = entries[name] if isinstance(entries, dict) else None
            print(f'  {name}' + (f' [{", ".join(types)}]' if types else '')
                  + ('  (WARNING: more than one node has this name: ROS cannot tell them apart; give one another '
                     'name or namespace)' if title == 'nodes' and name in graph['duplicates'] else ''))
    if not graph['settled']:
        print(f'(discovery was still changing after {max(LIMIT_S, args.wait):g} s: the graph may be incomplete)',
              file=sys.stderr)
    if not graph['nodes']:
        print(f'(no node in ROS domain {os.environ.get("ROS_DOMAIN_ID", "0")}: start one, e.g. ./dialfred launch nodes)',
              file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
