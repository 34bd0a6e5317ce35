"""Two "hosts" on this machine, for real: two network namespaces joined by a veth pair, each with its
own /dev/shm (so shared memory cannot carry DDS between them), run (a) a call from one host to a simulator
node on the other (one ROS domain, discovery on the namespaces' subnet) and an evaluation in two
shards, one per host, merged into the very results of the same run on one host, with no socket on any address but the subnet's and loopback;
and (b) two torchrun ranks of the performer's training (gloo over the veth pair), which end with the
weights of one process with the same global batch. The namespaces are removed whatever happens.

Needs root and `ip netns` (skipped otherwise); slow (about a minute)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from dialfred_bringup.paths import REPO

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(os.geteuid() != 0 or shutil.which('ip') is None or shutil.which('unshare') is None,
                                 reason='needs root, ip netns and unshare')]

SUBNET = '10.231.{}.{}'
TASKS = 16


def sh(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, check=check)


@pytest.fixture
def hosts():
    """Two hosts A and B: network namespaces (10.231.x.1 and .2 on a veth pair) and mount namespaces
    with a /dev/shm each (shared by the processes of one host, as on a real one). Yields (name,
    address, device, mount namespace file) per host; everything is removed whatever happens."""
    tag = f'{os.getpid() % 10000}'
    names = [f'dfa{tag}', f'dfb{tag}']
    third = os.getpid() % 250 + 1
    addresses = [SUBNET.format(third, 1), SUBNET.format(third, 2)]
    run = Path(f'/run/dialfred_hosts_{tag}')
    mounts = [run / f'mnt_{name}' for name in names]
    try:
        run.mkdir(parents=True, exist_ok=True)
        sh('mount', '--bind', str(run), str(run))
        sh('mount', '--make-private', str(run))
        for name, mnt in zip(names, mounts):
            sh('ip', 'netns', 'add', name)
            sh('ip', 'netns', 'exec', name, 'ip', 'link', 'set', 'lo', 'up')
            mnt.touch()
            sh('unshare', f'--mount={mnt}', '--propagation', 'private', 'true')
            sh('nsenter', f'--mount={mnt}', 'mount', '-t', 'tmpfs', 'tmpfs', '/dev/shm')
        sh('ip', 'link', 'add', f'va{tag}', 'type', 'veth', 'peer', 'name', f'vb{tag}')
        for name, dev, address in zip(names, [f'va{tag}', f'vb{tag}'], addresses):
            sh('ip', 'link', 'set', dev, 'netns', name)
            sh('ip', 'netns', 'exec', name, 'ip', 'addr', 'add', f'{address}/24', 'dev', dev)
            sh('ip', 'netns', 'exec', name, 'ip', 'link', 'set', dev, 'up')
            sh('ip', 'netns', 'exec', name, 'ip', 'route', 'add', '224.0.0.0/4', 'dev', dev)   # DDS multicast
        yield list(zip(names, addresses, [f'va{tag}', f'vb{tag}'], mounts))
    finally:
        for name in names:
            pids = sh('ip', 'netns', 'pids', name, check=False).stdout.split()
            for pid in pids:
                subprocess.run(['kill', '-9', pid], capture_output=True)
            sh('ip', 'netns', 'del', name, check=False)
        for mnt in mounts:
            sh('umount', str(mnt), check=False)
        sh('umount', str(run), check=False)
        shutil.rmtree(run, ignore_errors=True)
        assert not any(n in sh('ip', 'netns', 'list').stdout for n in names) and not run.exists()


def on_host(host: tuple, command: list[str]) -> list[str]:
    """`command` on `host`: in its network namespace and its mount namespace (its own /dev/shm)."""
    name, _, _, mnt = host
    return ['nsenter', f'--net=/run/netns/{name}', f'--mount={mnt}', *command]


def clean_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(('ROS_AUTOMATIC', 'ROS_STATIC', 'FASTRTPS', 'DIALFRED_NETWORK', 'DIALFRED_SAID',
                                'ROS_DOMAIN_ID'))}
    return {**env, **extra}


def without_wall(path: Path) -> list[dict]:
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    for r in rows:
        r.pop('wall_s')
    return sorted(rows, key=lambda r: r['task_id'])


def test_an_evaluation_sharded_over_two_hosts_merges_into_the_one_host_run(hosts, tmp_path):
    (a, addr_a, _, _), (b, addr_b, _, _) = hosts
    env = clean_env(ROS_DOMAIN_ID='42', ROS_AUTOMATIC_DISCOVERY_RANGE='SUBNET')
    eval_args = [sys.executable, '-m', 'dialfred_bringup.launch', 'eval', '--split', 'valid_unseen', '--agent',
                 'expert', '--limit', str(TASKS), '--workers', '1', '--no-progress']
    # Discovery and calls across the hosts: host A resets the simulator node that host B runs
    nodes_b = subprocess.Popen(on_host(hosts[1], [sys.executable, '-m', 'dialfred_bringup.launch', 'nodes',
                                                  '--resolution', '32']), env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, cwd=REPO)
    try:
        probe = subprocess.run(on_host(hosts[0], [sys.executable, '-c', PROBE]), env=env, capture_output=True,
                               text=True, cwd=REPO, timeout=180)
    finally:
        nodes_b.send_signal(signal.SIGINT)
        nodes_b.communicate(timeout=60)
    assert probe.stdout.strip().endswith('reset ok'), probe.stdout + probe.stderr
    shards = [subprocess.Popen(on_host(host, [*eval_args, '--shard', f'{k}/2', '--out', str(tmp_path / f'run_{k}.jsonl')]),
                               env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
              for k, host in enumerate(hosts)]
    sockets = []
    for _ in range(120):
        if all(p.poll() is not None for p in shards):
            break
        for host, address in ((a, addr_a), (b, addr_b)):
            sockets += [(host, address, line) for line in sh('ip', 'netns', 'exec', host, 'ss', '-H', '-lun').stdout
                        .splitlines()]
        subprocess.run(['sleep', '0.5'])
    outs = [p.communicate(timeout=300) for p in shards]
    for p, (out, err) in zip(shards, outs):
        assert p.returncode == 0, out[-2000:] + err[-2000:]
    assert 'DDS discovery reaches other hosts' in outs[0][1]                     # it said so
    for host, address, line in sockets:                       # nothing bound to an address outside the subnet
        local = line.split()[3].rsplit(':', 1)[0]
        assert local in ('0.0.0.0', '*', address) or local.startswith(('127.', '239.')), (host, line)
    merged = tmp_path / 'merged.jsonl'
    done = subprocess.run([sys.executable, '-m', 'dialfred_bringup.shards', str(tmp_path / 'run_0.jsonl'),
                           str(tmp_path / 'run_1.jsonl'), '--out', str(merged)], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 0, done.stderr
    one = tmp_path / 'one.jsonl'
    done = subprocess.run([*eval_args, '--out', str(one)], capture_output=True, text=True, cwd=REPO, env=clean_env())
    assert done.returncode == 0, done.stderr
    assert without_wall(merged) == without_wall(one) and len(without_wall(one)) == TASKS


PROBE = '''
import sys, rclpy
from dialfred_msgs.srv import SimReset
rclpy.init()
node = rclpy.create_node('probe')
client = node.create_client(SimReset, '/sim/reset')
if not client.wait_for_service(timeout_sec=60):
    sys.exit('no /sim/reset')
future = client.call_async(SimReset.Request(scene='FloorPlan1', seed=0))
rclpy.spin_until_future_complete(node, future, timeout_sec=60)
print('reset ok' if future.result() is not None and future.result().ok else 'reset failed')
'''


def test_two_ranks_on_two_hosts_train_to_the_weights_of_one_process(hosts, tmp_path):
    import torch

    from dialfred_performer.model import PerformerConfig, load_checkpoint
    from dialfred_performer.prepare import PrepareConfig, prepare
    from dialfred_performer.train import TrainConfig, train
    from dialfred_sim.dataclass_cli import to_argv
    folder = tmp_path / 'data'
    prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=4, out=str(folder), progress=False))
    model = PerformerConfig(resolution=64, d_model=32, heads=2, layers=1, ff=64, dropout=0.0, max_steps=64)
    base = dict(demonstrations=str(folder), model=model, epochs=2, batch_size=2, bucket=2, every_combination=False,
                warmup_updates=2, log_every=1, checkpoint_every=3, val_fraction=0.3, threads=1, device='cpu',
                progress=False)
    one = TrainConfig(out=str(tmp_path / 'one'), **base)
    train(one)
    local = TrainConfig(out=str(tmp_path / 'local'), **base)        # two processes on this host
    done = subprocess.run([sys.executable, '-m', 'torch.distributed.run', '--standalone', '--nproc_per_node', '2',
                           '-m', 'dialfred_performer.train', *to_argv(local)], capture_output=True, text=True, cwd=REPO,
                          env=clean_env())
    assert done.returncode == 0, done.stderr[-3000:]
    addr_a = hosts[0][1]
    cfg = TrainConfig(out=str(tmp_path / 'two'), **base)
    ranks = []
    for rank, host in enumerate(hosts):
        dev = host[2]
        cmd = [sys.executable, '-m', 'torch.distributed.run', '--nnodes', '2', '--node_rank', str(rank),
               '--nproc_per_node', '1', '--master_addr', addr_a, '--master_port', '29533',
               '-m', 'dialfred_performer.train', *to_argv(cfg)]
        ranks.append(subprocess.Popen(on_host(host, cmd), env=clean_env(GLOO_SOCKET_IFNAME=dev), cwd=REPO,
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    for p in ranks:
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0, out[-2000:] + err[-3000:]
    weights = {run: load_checkpoint(tmp_path / run / 'last.pt')[0].state_dict() for run in ('one', 'local', 'two')}
    # The two hosts compute exactly what two processes on one host do (the same gloo all-reduce) ...
    assert all(torch.equal(weights['two'][k], weights['local'][k]) for k in weights['one'])
    # ... which is the single process's training up to float32 rounding (tests/performer/test_performer_ddp.py)
    losses = {run: [json.loads(line)['loss'] for line in (tmp_path / run / 'metrics.jsonl').read_text().splitlines()
                    if json.loads(line).get('kind') == 'train'] for run in ('one', 'two')}
    assert len(losses['one']) == len(losses['two']) > 0
    assert all(abs(x - y) <= 1e-5 * abs(x) for x, y in zip(losses['one'], losses['two'])), losses
