"""The learned questioners shipped in the package: their names, what each is, where their files are.

Without torch, so that an option's help lists them from here (`policy` loads them)."""

from __future__ import annotations

from pathlib import Path

# The shipped checkpoints: name -> CHECKPOINTS / (name with '_' for '-') + '.pt'.
CHECKPOINTS = Path(__file__).resolve().parent / 'checkpoints'
# name -> how it was trained, where the name does not say it ('' for none); in the order the docs list them.
SHIPPED = {
    'pretrained': '',
    'rl-begin': '',
    'rl-anytime': 'every 5 steps',
    'rl-anytime-1': '',
    'rl-anytime-10': '',
    'rl-mc': 'when the performer is unsure',
    'rl-anytime-withhold-location': '',
    'rl-anytime-withhold-appearance': '',
    'rl-anytime-withhold-direction': '',
    'rl-anytime-no-dialogue': '',
    'map-rl-anytime': 'fine-tuned against the map performer',
    'rl-anytime-chained': 'fine-tuned under the chained protocol',
    'map-rl-anytime-chained': 'against the map performer, under the chained protocol',
}
SHIPPED_LEARNED = tuple(SHIPPED)


def shipped_list() -> str:
    """The shipped names for a help text: 'pretrained, rl-begin, rl-anytime (every 5 steps), ...'."""
    return ', '.join(f'{name} ({note})' if note else name for name, note in SHIPPED.items())
