"""`./dialfred graph`: the running ROS graph in this ROS domain, as `ros2 node list`, `ros2 topic list -t`,
`ros2 service list -t` and `ros2 action list` would show it (there is no `ros2` CLI on PyPI).

Discovery takes a moment: the graph is read after `--wait` seconds (default 2). Actions appear as their
hidden services and topics (`<name>/_action/...`) and are listed once, by name. `--json` prints one JSON
object instead of the four lists.
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


def read_graph(node, wait_s: float) -> dict:
    """{'nodes', 'topics', 'services', 'actions'} of the graph `node` sees after `wait_s` seconds."""
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    me = node.get_fully_qualified_name()
    nodes = sorted(f'{ns.rstrip("/")}/{name}' for name, ns in node.get_node_names_and_namespaces()
                   if f'{ns.rstrip("/")}/{name}' != me)
    topics = {name: types for name, types in node.get_topic_names_and_types()}
    services = {name: types for name, types in node.get_service_names_and_types()}
    actions = sorted({name.split(ACTION_MARK)[0] for name in (*topics, *services) if ACTION_MARK in name})
    own = (f'{me}/', '/rosout', '/parameter_events')     # this reader's own endpoints and ROS's own topics

    def keep(name: str) -> bool:
        return ACTION_MARK not in name and not name.startswith(own[0]) and name not in own[1:]

    return {'nodes': nodes,
            'topics': {n: t for n, t in sorted(topics.items()) if keep(n)},
            'services': {n: t for n, t in sorted(services.items()) if keep(n) and not _parameter_service(n)},
            'actions': actions}


def _parameter_service(name: str) -> bool:
    """Every node's own parameter services (`ros2 service list` shows them; they say nothing of the graph)."""
    return name.rsplit('/', 1)[-1] in ('describe_parameters', 'get_parameter_types', 'get_parameters',
                                       'get_type_description', 'list_parameters', 'set_parameters',
                                       'set_parameters_atomically')


def main(argv=None) -> int:
    ap = Parser(prog='./dialfred graph', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--wait', type=float, default=2.0, help='seconds of discovery before the graph is read (default 2)')
    ap.add_argument('--json', action='store_true', help='one JSON object instead of the lists')
    args = ap.parse_args(argv)
    if not 0 <= args.wait <= 600:
        ap.error(f'--wait must be 0 to 600 seconds, got {args.wait}')
    rclpy.init()
    try:
        node = rclpy.create_node('dialfred_graph_reader', start_parameter_services=False, enable_rosout=False)
        graph = read_graph(node, args.wait)
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
            print(f'  {name}' + (f' [{", ".join(types)}]' if types else ''))
    if not graph['nodes']:
        print(f'(no node in ROS domain {os.environ.get("ROS_DOMAIN_ID", "0")}: start one, e.g. ./dialfred launch nodes)',
              file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
