"""A frozen config dataclass as the command line (CleanRL's `Args` habit, without a dependency).

`parse(Config, argv)` builds argparse from the dataclass's fields: one `--flag` per field (nested
dataclass fields are flattened: `TrainConfig.model.d_model` is `--d-model`), the field's type, its
default and the `help` of its metadata; bools are `--flag / --no-flag`. A ValueError raised by the
config's `__post_init__` becomes argparse's usage error. `to_argv(config)` is the inverse: the flags
that rebuild `config`, stored in checkpoints as the command that made them.
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import typing
from typing import Any, Iterator, Optional, Sequence, TypeVar

C = TypeVar('C')
SCALARS = (int, float, str, bool)

def arg(default: Any, help: str, **kwargs) -> Any:  # noqa: A002 - argparse's name
    """A config field with its help text."""
    return dataclasses.field(default=default, metadata={'help': help}, **kwargs)


def flat_fields(cls, prefix: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], dataclasses.Field, type]]:
    """(path, field, type) of every scalar field of `cls`, nested dataclasses flattened."""
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            yield from flat_fields(tp, prefix + (f.name,))
        elif tp in SCALARS:
            yield prefix + (f.name,), f, tp
        else:
            raise TypeError(f'{cls.__name__}.{f.name}: the command line takes {SCALARS}, not {tp}')


def flag(path: tuple[str, ...]) -> str:
    return '--' + path[-1].replace('_', '-')


def _default(f: dataclasses.Field) -> Any:
    return f.default_factory() if f.default is dataclasses.MISSING else f.default


def parser_for(cls, description: str = '', prog: Optional[str] = None) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog=prog, description=description or (cls.__doc__ or '').split('\n\n')[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    seen: dict[str, tuple] = {}
    for path, f, tp in flat_fields(cls):
        name = flag(path)
        if name in seen:
            raise TypeError(f'{cls.__name__}: {".".join(path)} and {".".join(seen[name])} would both be {name}')
        seen[name] = path
        help_text = f.metadata.get('help') or (f'the field {".".join(path)} of the config' if len(path) > 1 else '')
        help_text = help_text.replace('%', '%%')        # argparse formats help with %
        if tp is bool:
            ap.add_argument(name, dest='.'.join(path), action=argparse.BooleanOptionalAction,
                            default=_default(f), help=help_text)
        else:
            ap.add_argument(name, dest='.'.join(path), type=tp, default=_default(f), help=help_text,
                            metavar=tp.__name__.upper())
    return ap


def build(cls, values: dict[str, Any], prefix: tuple[str, ...] = ()):
    """An instance of `cls` from {'a.b': value} (dotted paths of `flat_fields`)."""
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in dataclasses.fields(cls):
        path = prefix + (f.name,)
        if dataclasses.is_dataclass(hints[f.name]):
            kwargs[f.name] = build(hints[f.name], values, path)
        elif '.'.join(path) in values:
            kwargs[f.name] = values['.'.join(path)]
    return cls(**kwargs)


def parse(cls: type[C], argv: Optional[Sequence[str]] = None, description: str = '',
          prog: Optional[str] = None) -> C:
    """The config of the command line `argv` (default: sys.argv[1:]); exits with a usage error
    (status 2) naming the problem when a value is not acceptable."""
    ap = parser_for(cls, description, prog)
    ns = ap.parse_args(argv)
    try:
        return build(cls, vars(ns))
    except (ValueError, TypeError) as exc:
        ap.error(str(exc))


def to_argv(config) -> list[str]:
    """The flags that rebuild `config` with `parse` (every field, so defaults may change safely)."""
    out = []
    for path, _, tp in flat_fields(type(config)):
        value = config
        for name in path:
            value = getattr(value, name)
        if tp is bool:
            out.append(flag(path) if value else '--no-' + flag(path)[2:])
        else:
            out += [flag(path), str(value)]
    return out


def command_line(module: str, config) -> str:
    return shlex.join(['python', '-m', module, *to_argv(config)])


def config_changes(saved: dict, cfg, allowed: Sequence[str]) -> dict:
    """{field: (saved value, value now)} for each field of the dataclass config `cfg` that differs
    from `saved` (the config a run was started with, as a dict), except the fields in `allowed`:
    what makes a --resume of that run refuse."""
    now = dataclasses.asdict(cfg)
    return {k: (saved.get(k), now[k]) for k in now if k not in allowed and saved.get(k) != now[k]}
