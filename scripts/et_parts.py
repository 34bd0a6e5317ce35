#!/usr/bin/env python3
"""Write a performer checkpoint's frozen perception network and its vocabulary as files of their own, for a
training run that fine-tunes it (`train-performer --init CKPT --perception OUT/perception.pt --vocabulary
OUT/vocabulary.json`: a fine-tune must see through the same network and read the same words).

    ./dialfred env python scripts/et_parts.py [--checkpoint CKPT] --out DIR
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from dialfred_performer.shipped import SHIPPED_CHECKPOINT
from dialfred_performer.perception import Perception, PerceptionNetConfig, save_perception
from dialfred_performer.train import load_checkpoint


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--checkpoint', default=str(SHIPPED_CHECKPOINT), help='a performer checkpoint (default: the shipped et.pt)')
    ap.add_argument('--out', required=True, help='folder for perception.pt and vocabulary.json')
    args = ap.parse_args()
    model, vocab, _ = load_checkpoint(Path(args.checkpoint))
    if model.config.visual != 'perception':
        print(f'error: {args.checkpoint} sees through its own convolutions, not a perception network', file=sys.stderr)
        return 2
    net = Perception(PerceptionNetConfig(**json.loads(model.config.perception_net)))
    net.load_state_dict({k[len('visual.net.'):]: v for k, v in model.state_dict().items() if k.startswith('visual.net.')})
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    save_perception(out / 'perception.pt', net)
    vocab.save(out / 'vocabulary.json')
    print(json.dumps({'perception': str(out / 'perception.pt'), 'vocabulary': str(out / 'vocabulary.json'),
                      'words': len(vocab)}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
