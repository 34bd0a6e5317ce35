"""Where the performer's trained checkpoint is shipped in the package (no imports: every module may read it)."""

from pathlib import Path

# The trained checkpoint shipped in the package (the command that made it is stored inside it and in
# docs/figures.md); the default of the performer node, `launch eval --agent/--performer et` and the demo.
SHIPPED_CHECKPOINT = Path(__file__).resolve().parent / 'checkpoints' / 'et.pt'
