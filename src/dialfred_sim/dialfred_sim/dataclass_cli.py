"""A config dataclass as the command line (CleanRL's `Args` habit, without a dependency).

Every entry point keeps its options in one dataclass; this module makes its argparse, so that a
default, a choice or a help text is written once, in the field:

    @dataclass
    class Config:
        split: str = arg('valid_unseen', 'a shipped split', choices=SPLITS, group='tasks')
        tasks_file: Optional[Path] = arg(None, 'a split file of your own', flag='--tasks', group='tasks')
        shard: Optional[tuple] = arg(None, 'shard K of N', parse=parse_shard, show=show_shard, metavar='K/N')

    config = parse(Config)                      # or parser_for(Config, parser=a_subparser) + from_args

One `--flag` per field (nested dataclass fields are flattened: `TrainConfig.model.d_model` is
`--d-model`), of the field's type (int, float, str, bool, Path, each possibly Optional; any other type
needs `parse`), its default and the `help` of its metadata; bools are `--flag / --no-flag`. What `arg`
takes besides: `flag` (another name), `choices`, `parse` (text -> value; a ValueError is the usage
error), `show` (value -> text, for `to_argv`), `const` (the flag may come without a value:
`--foxglove` = `--foxglove 8765`), `aliases` (words that stand for a value: `--questioner none` is
''; an Optional field takes `none` for None), `group` (fields of one group are mutually exclusive on the command line) and `metavar`.

A ValueError raised by the config's `__post_init__` becomes argparse's usage error. `to_argv(config)`
is the inverse: the flags that rebuild `config`, stored in checkpoints as the command that made them.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import math
import re
import shlex
import types
import typing
from pathlib import Path
from typing import Any, Callable, Iterator, Optional, Sequence, TypeVar, Union

C = TypeVar('C')
SCALARS = (int, float, str, bool, Path)
REQUIRED = dataclasses.MISSING        # arg(REQUIRED, ...): a field the command line must give
_UNSET = object()


def arg(default: Any, help: str, *, flag: Optional[str] = None,  # noqa: A002 - argparse's name
        choices: Optional[Union[Sequence, Callable[[], Sequence]]] = None, parse: Optional[Callable[[str], Any]] = None,
        show: Optional[Callable[[Any], str]] = None, const: Any = _UNSET, aliases: Optional[dict] = None,
        group: Optional[str] = None, metavar: Optional[str] = None, positional: bool = False, **kwargs) -> Any:
    """A config field with its help text and how the command line writes it (see the module);
    `default=REQUIRED`: the command line must give it. `choices` may be a function giving them when
    a command line is read (values of a registry that may grow after the config class is made)."""
    if choices is not None and not callable(choices):
        choices = tuple(choices)
    meta = {'help': help, 'flag': flag, 'choices': choices,
            'parse': parse, 'show': show, 'const': const, 'aliases': dict(aliases or {}), 'group': group,
            'metavar': metavar, 'positional': positional or None}
    return dataclasses.field(default=default, metadata={k: v for k, v in meta.items()
                                                        if v is not None and v is not _UNSET and v != {}}, **kwargs)


def check_bounds(config, *, at_least_one: Sequence[str] = (), non_negative: Sequence[str] = (),
                 positive: Sequence[str] = (), fractions: Sequence[str] = ()) -> None:
    """The numeric checks a config's `__post_init__` makes, worded alike everywhere: a ValueError naming
    the first field of `config` that is below 1 (`at_least_one`), below 0 (`non_negative`), not a finite
    number above 0 (`positive`, learning rates) or outside [0, 1] (`fractions`)."""
    for name in at_least_one:
        if getattr(config, name) < 1:
            raise ValueError(f'{name} must be at least 1, got {getattr(config, name)}')
    for name in non_negative:
        if getattr(config, name) < 0:
            raise ValueError(f'{name} must be >= 0, got {getattr(config, name)}')
    for name in positive:
        value = getattr(config, name)
        if not (value > 0 and math.isfinite(value)):
            raise ValueError(f'{name} must be a positive number, got {value}')
    for name in fractions:
        if not 0.0 <= getattr(config, name) <= 1.0:
            raise ValueError(f'{name} must be in [0, 1], got {getattr(config, name)}')


def _unwrap(tp) -> tuple[Any, bool]:
    """(the type, whether None is allowed) of a field's annotation: Optional[X] -> (X, True)."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0], True
    return tp, False


def _item_type(tp):
    """X of a list[X] field (given as one or more words), else None."""
    return typing.get_args(tp)[0] if typing.get_origin(tp) is list else None


def flat_fields(cls, prefix: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], dataclasses.Field, type]]:
    """(path, field, type) of every command-line field of `cls`, nested dataclasses flattened; the
    type has Optional taken off."""
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp, _ = _unwrap(hints[f.name])
        if dataclasses.is_dataclass(tp):
            yield from flat_fields(tp, prefix + (f.name,))
        elif tp in SCALARS or 'parse' in f.metadata or _item_type(tp) in SCALARS:
            yield prefix + (f.name,), f, tp
        else:
            raise TypeError(f'{cls.__name__}.{f.name}: the command line takes {[t.__name__ for t in SCALARS]} '
                            f'(or a field with parse=), not {tp}')


def flag(path: tuple[str, ...], f: Optional[dataclasses.Field] = None) -> str:
    return (f.metadata.get('flag') if f is not None else None) or '--' + path[-1].replace('_', '-')


def _default(f: dataclasses.Field) -> Any:
    if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
        return REQUIRED
    return f.default_factory() if f.default is dataclasses.MISSING else f.default


def _aliases(f: dataclasses.Field, optional: bool) -> dict:
    """The words that stand for a value: the field's `aliases`, and 'none' for None where it may be None."""
    return {'none': None, **f.metadata.get('aliases', {})} if optional else f.metadata.get('aliases', {})


def _shown(f: dataclasses.Field, optional: bool, value) -> str:
    """A value as the command line writes it."""
    words = [k for k, v in _aliases(f, optional).items() if v == value and type(v) is type(value)]
    return words[0] if words else f.metadata.get('show', str)(value)


def _choices(meta) -> Optional[tuple]:
    """A field's choices now (None: any value)."""
    choices = meta.get('choices')
    return tuple(choices()) if callable(choices) else choices


def _converter(f: dataclasses.Field, tp, optional: bool) -> Callable[[str], Any]:
    """text -> the field's value: an alias, else `parse` or the type, then the choices checked."""
    aliases, choices, parse_text = _aliases(f, optional), _choices(f.metadata), f.metadata.get('parse')
    default = _default(f)

    def convert(text: str):
        if text in aliases:
            return aliases[text]
        if tp is Path and text == '':       # Path('') would be '.', the current folder
            if optional:
                return None
            raise argparse.ArgumentTypeError('an empty path')
        if isinstance(default, str) and text == default:   # argparse passes a str default through here too
            return text     # (not `default`: argparse tells a given value from the default by identity)
        try:
            value = parse_text(text) if parse_text else tp(text)
        except (ValueError, TypeError) as exc:
            raise argparse.ArgumentTypeError(str(exc) if parse_text else f'invalid {tp.__name__} value: {text!r}') from None
        if choices is not None and value not in choices:
            raise argparse.ArgumentTypeError(f'{text!r} is not one of {", ".join(map(str, (*aliases, *choices)))}')
        return value

    convert.__name__ = tp.__name__
    return convert


def add_fields(cls, parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add one option per field of `cls` to `parser` (a parser or a subparser); returns it."""
    seen: dict[str, tuple] = {}
    groups: dict[str, Any] = {}
    optional = _optional_paths(cls)
    for path, f, tp in flat_fields(cls):
        name = flag(path, f)
        if name in seen:
            raise TypeError(f'{cls.__name__}: {".".join(path)} and {".".join(seen[name])} would both be {name}')
        seen[name] = path
        meta = f.metadata
        help_text = meta.get('help') or (f'the field {".".join(path)} of the config' if len(path) > 1 else '')
        required = _default(f) is REQUIRED
        if tp is not bool and not required:
            help_text = f'{help_text} (default: {_shown(f, path in optional, _default(f))})'.lstrip()
        help_text = help_text.replace('%', '%%')        # argparse formats help with %
        target = parser
        if meta.get('group'):
            if meta['group'] not in groups:
                groups[meta['group']] = parser.add_mutually_exclusive_group()
            target = groups[meta['group']]
        if tp is bool:
            target.add_argument(name, dest='.'.join(path), action=argparse.BooleanOptionalAction,
                                default=_default(f), help=f'{help_text} (default: {flag(path, f) if _default(f) else "--no-" + flag(path, f)[2:]})'.lstrip())
            continue
        metavar = meta.get('metavar')
        if metavar is None and 'choices' in meta:
            metavar = '{' + ','.join(map(str, (*_aliases(f, path in optional), *_choices(meta)))) + '}'
        item = _item_type(tp)
        kwargs = dict(dest='.'.join(path), type=_converter(f, item or tp, path in optional), help=help_text,
                      metavar=metavar or (item or tp).__name__.upper())
        if item is not None:
            kwargs['nargs'] = '+' if required else '*'
        if meta.get('positional'):
            if not required:
                kwargs['nargs'] = kwargs.get('nargs', '?')
                kwargs['default'] = _default(f)
            kwargs['metavar'] = metavar or path[-1]
            del kwargs['dest']
            target.add_argument('.'.join(path), **kwargs)
            continue
        if required:
            kwargs['required'] = True
        else:
            kwargs['default'] = _default(f)
        if 'const' in meta:
            kwargs.update(nargs='?', const=meta['const'])
        if meta.get('group'):
            # argparse tells a given value from the default by identity, and an interned string given
            # on the command line is its default: a grouped field's default is a marker that `build`
            # replaces with the field's default.
            kwargs['default'] = _UNSET
        target.add_argument(name, **kwargs)
    return parser


_USED = '_dialfred_parser'     # the namespace attribute naming the innermost parser that read the arguments


class Parser(argparse.ArgumentParser):
    """argparse's parser whose usage error is one line on stderr (status 2) that names the (sub)command it
    belongs to and suggests the nearest option or value: `./dialfred launch eval: error: unrecognized
    arguments: --questoner (did you mean --questioner?); --help lists the options`. Subcommands made with
    `add_subparsers` are Parsers too."""

    def parse_known_args(self, args=None, namespace=None):
        namespace, extras = super().parse_known_args(args, namespace)
        if not hasattr(namespace, _USED):          # a subcommand's parser returns first: it names itself
            setattr(namespace, _USED, self)
        return namespace, extras

    def parse_args(self, args=None, namespace=None):
        namespace, extras = self.parse_known_args(args, namespace)
        used = getattr(namespace, _USED, self)
        delattr(namespace, _USED)
        if extras:
            used.error(f'unrecognized arguments: {" ".join(extras)}')
        return namespace

    def options(self) -> list[str]:
        return [o for a in self._actions for o in a.option_strings if o.startswith('--')]

    def suggestion(self, message: str) -> str:
        """' (did you mean X?)' for the misspelled option or value that `message` names, or ''."""
        choice = (re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
                  or re.search(r"'([^']*)' is not one of (.*)", message))
        if choice:
            words = re.findall(r"'([^']*)'", choice.group(2)) or [w.strip() for w in choice.group(2).split(',')]
            near = difflib.get_close_matches(choice.group(1), words, n=1, cutoff=0.5)
            return f' (did you mean {near[0]}?)' if near else ''
        wrong = re.findall(r'(?:unrecognized arguments: |ambiguous option: )(.*)', message)
        for word in (wrong[0].split() if wrong else []):
            if word.startswith('--'):
                near = difflib.get_close_matches(word.split('=')[0], self.options(), n=1, cutoff=0.6)
                if near:
                    return f' (did you mean {near[0]}?)'
        return ''

    def error(self, message: str):
        self.exit(2, f'{self.prog}: error: {message}{self.suggestion(message)}; {self.prog} --help lists the '
                     'options\n')


def parser_for(cls, description: str = '', prog: Optional[str] = None, **kwargs) -> argparse.ArgumentParser:
    """A parser of `cls`'s fields (each help text ends with the default); `kwargs` go to ArgumentParser."""
    ap = Parser(prog=prog, description=description or (cls.__doc__ or '').split('\n\n')[0], **kwargs)
    return add_fields(cls, ap)


def _optional_paths(cls, prefix: tuple[str, ...] = ()) -> set:
    """The paths of the fields of `cls` that may be None (Optional[X])."""
    hints, out = typing.get_type_hints(cls), set()
    for f in dataclasses.fields(cls):
        tp, optional = _unwrap(hints[f.name])
        if dataclasses.is_dataclass(tp):
            out |= _optional_paths(tp, prefix + (f.name,))
        elif optional:
            out.add(prefix + (f.name,))
    return out


def build(cls, values: dict[str, Any], prefix: tuple[str, ...] = ()):
    """An instance of `cls` from {'a.b': value} (dotted paths of `flat_fields`; other keys ignored)."""
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in dataclasses.fields(cls):
        path = prefix + (f.name,)
        tp, _ = _unwrap(hints[f.name])
        if dataclasses.is_dataclass(tp):
            kwargs[f.name] = build(tp, values, path)
        elif values.get('.'.join(path), _UNSET) is not _UNSET:
            kwargs[f.name] = values['.'.join(path)]
    return cls(**kwargs)


def from_args(cls: type[C], namespace: argparse.Namespace, parser: argparse.ArgumentParser) -> C:
    """The config of parsed arguments (options added beside the fields are ignored); a ValueError of
    the config exits with `parser`'s usage error."""
    try:
        return build(cls, vars(namespace))
    except (ValueError, TypeError) as exc:
        parser.error(str(exc))


def parse(cls: type[C], argv: Optional[Sequence[str]] = None, description: str = '',
          prog: Optional[str] = None, **kwargs) -> C:
    """The config of the command line `argv` (default: sys.argv[1:]); exits with a usage error
    (status 2) naming the problem when a value is not acceptable."""
    ap = parser_for(cls, description, prog, **kwargs)
    return from_args(cls, ap.parse_args(argv), ap)


def to_argv(config) -> list[str]:
    """The flags that rebuild `config` with `parse`: every field, so defaults may change safely (of
    a mutually exclusive group, the one field not at its default, else the group's first)."""
    fields = []
    optional = _optional_paths(type(config))
    for path, f, tp in flat_fields(type(config)):
        value = config
        for name in path:
            value = getattr(value, name)
        fields.append((path, f, tp, value))
    groups: dict[str, tuple] = {}
    for path, f, _, value in fields:
        group = f.metadata.get('group')
        if group and (group not in groups or value != _default(f)):
            groups[group] = path
    out, positionals = [], []
    for path, f, tp, value in fields:
        if f.metadata.get('group') and groups[f.metadata['group']] != path:
            continue
        words = ([_shown(f, path in optional, v) for v in value] if _item_type(tp) is not None
                 else [_shown(f, path in optional, value)])
        if f.metadata.get('positional'):
            positionals += words
        elif tp is bool:
            out.append(flag(path, f) if value else '--no-' + flag(path, f)[2:])
        else:
            out += [flag(path, f), *words]
    return positionals + out


def command_line(module: str, config) -> str:
    return shlex.join(['python', '-m', module, *to_argv(config)])


def config_changes(saved: dict, cfg, allowed: Sequence[str]) -> dict:
    """{field: (saved value, value now)} for each field of the dataclass config `cfg` that differs
    from `saved` (the config a run was started with, as a dict), except the fields in `allowed`:
    what makes a --resume of that run refuse. A field the saved config lacks (the run began before the field
    existed) counts as its default, the behaviour the run had then."""
    now = dataclasses.asdict(cfg)
    defaults = {f.name: f.default for f in dataclasses.fields(cfg) if f.default is not dataclasses.MISSING}
    was = {k: saved.get(k, defaults.get(k)) for k in now}
    return {k: (was[k], now[k]) for k in now if k not in allowed and was[k] != now[k]}


def _markdown_text(text: str) -> str:
    """Help text in a Markdown table cell: '|' escaped, and '<' '>' outside `code` as entities (a
    renderer would take <split> for a tag)."""
    parts = text.replace('|', '\\|').split('`')
    return '`'.join(p if k % 2 else p.replace('<', '&lt;').replace('>', '&gt;') for k, p in enumerate(parts))


def markdown_options(cls, extra: Sequence[tuple[str, str, str]] = ()) -> str:
    """A Markdown table of the command line of `cls` (flag, meaning, default), plus `extra` rows
    (flag, meaning, default) for options a job adds beside the fields: the docs' option tables are
    made from the fields, so a default is written once."""
    optional = _optional_paths(cls)
    rows = ['| option | meaning | default |', '|---|---|---|']
    groups: dict[str, str] = {}
    for path, f, tp in flat_fields(cls):
        name = flag(path, f)
        meta = f.metadata
        if meta.get('positional'):
            option = f'`{meta.get("metavar") or path[-1]}`'
            default = '(required)' if _default(f) is REQUIRED else f'`{_shown(f, path in optional, _default(f))}`'
        elif tp is bool:
            option, default = f'`{name}` / `--no-{name[2:]}`', f'`{name if _default(f) else "--no-" + name[2:]}`'
        elif _default(f) is REQUIRED:
            option, default = f'`{name} {meta.get("metavar") or tp.__name__.upper()}`', '(required)'
        else:
            if 'choices' in meta:
                value = '{' + ','.join(map(str, (*_aliases(f, path in optional), *_choices(meta)))) + '}'
            else:
                value = meta.get('metavar') or tp.__name__.upper()
            option = f'`{name} [{value}]`' if 'const' in meta else f'`{name} {value}`'
            default = f'`{_shown(f, path in optional, _default(f))}`'
        meaning = _markdown_text(' '.join((meta.get('help') or '').split()))
        if meta.get('group'):
            others = groups.setdefault(meta['group'], name)
            if others != name:
                meaning = f'instead of `{others}`: {meaning}'
        rows.append(f'| {option} | {meaning} | {default} |')
    rows += [f'| `{flag_text}` | {meaning} | `{default}` |' for flag_text, meaning, default in extra]
    return '\n'.join(rows) + '\n'
