"""A checkpoint's plain values (its config, vocabulary, command, commit), read without torch.

A file of `torch.save` is a zip whose `data.pkl` holds the pickled dict and refers to each tensor's
bytes, kept beside it, by a persistent id. Reading that pickle alone, with every tensor left as None,
gives the rest of the dict in milliseconds and without importing torch: what a config needs to settle
its defaults (the performer's camera, `model_registry.camera_resolution`) before anything is played.
Only plain values, `collections.OrderedDict` and torch's tensor rebuilders are accepted; any other class
in the pickle is refused, so no code of a crafted file runs. The weights are read, and checked, by
`model.read_state` / `load_checkpoint` when the model is built.
"""

from __future__ import annotations

import collections
import io
import pickle
import zipfile
from pathlib import Path


class HeaderError(ValueError):
    """The file is not a zip-format torch checkpoint whose pickle holds plain values and tensors."""


def _no_tensor(*args, **kwargs) -> None:
    return None


class _Unpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        if module == 'collections' and name == 'OrderedDict':
            return collections.OrderedDict
        if module == 'torch' or module.startswith('torch.'):
            return _no_tensor          # a tensor rebuilder or storage type: the tensor becomes None
        raise pickle.UnpicklingError(f'{module}.{name} is not a value of a checkpoint')

    def persistent_load(self, pid) -> None:
        return None                    # a tensor's storage, kept outside the pickle


def read_header(path: Path) -> dict:
    """The dict saved in checkpoint `path`, its tensors None. FileNotFoundError if there is none;
    HeaderError for a file that is not such a checkpoint (a damaged or legacy one: `model.read_state`
    says more)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f'no checkpoint at {path}')
    try:
        with zipfile.ZipFile(path) as archive:
            pickles = [n for n in archive.namelist() if n == 'data.pkl' or n.endswith('/data.pkl')]
            if len(pickles) != 1:
                raise HeaderError(f'{path}: {len(pickles)} data.pkl in the archive, a checkpoint has 1')
            state = _Unpickler(io.BytesIO(archive.read(pickles[0]))).load()
    except (zipfile.BadZipFile, pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError) as exc:
        if isinstance(exc, HeaderError):
            raise
        raise HeaderError(f'{path}: not a readable checkpoint ({type(exc).__name__}: {str(exc)[:200]})') from None
    if not isinstance(state, dict):
        raise HeaderError(f'{path}: expected a dict, found {type(state).__name__}')
    return state
