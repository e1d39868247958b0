"""The command line derived from the settings' declarations (``settings.declare``).

For any configuration whose fields were declared with ``settings.declare.setting``: its
options (:func:`add_options`), a comma-separated list of one setting's values
(:func:`add_list_options`, ``--seeds 0,1,2``) and the configuration from parsed options
(:func:`config_from_args`). Nothing else in the package calls ``add_argument`` for a setting
(``tests/test_option_sources.py``).

Only light modules here: the scripts build their parsers from these before NumPy, pandas, simpy
or TensorFlow load (``tests/test_first_answer.py``).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

from yafs_safetail.settings.declare import Setting, field_of, has_setting, setting_of, shown_value


def _fields_of(config_class: type, only: Iterable[str] | None,
               exclude: Iterable[str] = ()) -> list[dataclasses.Field[Any]]:
    if only is None:
        left_out = set(exclude)
        return [f for f in fields(config_class)
                if f.name not in left_out and has_setting(f) and setting_of(f).option(f.name)]
    return [field_of(config_class, name) for name in only]


class _DeprecatedOption(argparse.Action):
    """An older spelling of an option: stores as the option does, and says what replaces it."""

    def __init__(self, option_strings: Sequence[str], dest: str, replacement: str = "",
                 **kwargs: Any) -> None:
        super().__init__(option_strings, dest, **kwargs)
        self.replacement = replacement

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        # On stderr at once: logging is set up only after the arguments are parsed.
        print(f"warning: {option_string} is deprecated; use {self.replacement}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def _value_keywords(item: dataclasses.Field[Any], about: Setting, flag: str) -> dict[str, Any]:
    """How argparse reads one value of a setting: its type, choices and placeholder."""
    keywords: dict[str, Any] = {}
    if about.check is not None and about.check.choices is not None:
        keywords["choices"] = about.check.choices
        if about.check.parse is not None:
            keywords["type"] = about.check.parse
    elif about.check is not None and about.check.parse is not None:
        keywords["type"] = about.check.parse
    elif item.type in ("Path", "Path | None"):
        keywords["type"] = Path
    if about.metavar is not None:
        keywords["metavar"] = about.metavar
    elif "choices" not in keywords:  # named after the option, as argparse would
        keywords["metavar"] = flag.lstrip("-").replace("-", "_").upper()
    return keywords


def add_options(parser: argparse._ActionsContainer, config_class: type,
                only: Iterable[str] | None = None, exclude: Iterable[str] = (),
                defaults: Any = None, **changes: Mapping[str, Any]) -> None:
    """Add the command-line options of a configuration's fields to ``parser``.

    Each option's destination is the field's name, so :func:`config_from_args` can read it.

    Args:
        parser: the parser (or an argument group of it).
        config_class: a dataclass whose fields were declared with :func:`setting`.
        only: the fields to add, in this order (None: every field that has an option).
        exclude: with ``only=None``, fields not to add (a script adding the rest of the fields,
            so that a field declared later becomes its option too).
        defaults: an instance of ``config_class`` whose values are this command's defaults
            (its own starting point, e.g. the load sweep's 50 users); None: the declarations'.
        changes: per field, argparse keywords that differ in this script (``default``,
            ``help``, ``required``...).

    Raises:
        TypeError: a field without an option, or a flag that could only set its default.
    """
    for item in _fields_of(config_class, only, exclude):
        about = setting_of(item)
        flag = about.option(item.name)
        if not flag:
            raise TypeError(f"{item.name}: has no command-line option")
        default = item.default if defaults is None else getattr(defaults, item.name)
        keywords: dict[str, Any] = {"dest": item.name, "help": about.help}
        if about.action in ("store_true", "store_false"):
            if default != (about.action == "store_false"):
                raise TypeError(f"{item.name}: {flag} would only set its default {default!r}")
            keywords.update(action=about.action, default=default)
            if about.negation is not None:  # the flag and its explicit default, one or the other
                both = parser.add_mutually_exclusive_group()
                both.add_argument(flag, **keywords, **changes.get(item.name, {}))
                both.add_argument(about.negation, dest=item.name, default=default,
                                  action="store_false" if about.action == "store_true" else "store_true",
                                  help=f"the default, without {flag} (kept for older scripts)")
                continue
        elif about.action == "append":
            keywords.update(action="append", default=[])
        else:
            keywords["default"] = default
            keywords.update(_value_keywords(item, about, flag))
            if default != item.default and not isinstance(default, bool):  # the command's own default
                keywords["help"] = f"{about.help} (default here: {shown_value(default)})"
        keywords.update(changes.get(item.name, {}))
        parser.add_argument(flag, **keywords)
        for alias in about.deprecated:  # hidden from --help: only the option to use is listed
            old = {key: value for key, value in keywords.items() if key not in ("action", "help")}
            parser.add_argument(alias, action=_DeprecatedOption, replacement=flag, help=argparse.SUPPRESS, **old)


def add_list_options(parser: argparse._ActionsContainer, config_class: type, flags: Mapping[str, str],
                     ascending: bool = False, **changes: Mapping[str, Any]) -> None:
    """Options that take several values of one setting, comma-separated (``--seeds 0,1,2`` for
    the setting ``seed``): each value read and checked as the setting's own option reads and
    checks one, none given twice. The destination is the option's name (``seeds``).

    Args:
        parser: the parser (or an argument group of it).
        config_class: the configuration that declares the settings.
        flags: setting name -> the option taking a list of its values.
        ascending: return the values sorted (a grid whose order does not matter).
        changes: per setting, argparse keywords of the list option (``default``, ``help``);
            the default is None unless given.
    """
    for name, flag in flags.items():
        item = field_of(config_class, name)
        about = setting_of(item)
        one = _value_keywords(item, about, about.option(name) or flag)
        keywords: dict[str, Any] = {
            "dest": flag.lstrip("-").replace("-", "_"), "default": None,
            "help": f"several values of {about.option(name) or name}, comma-separated: {about.help}",
            "type": _list_of(about, one.get("type"), one.get("choices"), ascending),
            "metavar": f"{one.get('metavar', name.upper())},..."}
        keywords.update(changes.get(name, {}))
        parser.add_argument(flag, **keywords)


def _list_of(about: Setting, parse: Callable[[str], Any] | None, choices: Sequence[Any] | None,
             ascending: bool) -> Callable[[str], tuple[Any, ...]]:
    """The argparse type of a list option: every value as the one-value option reads it."""
    def read(text: str) -> tuple[Any, ...]:
        values = []
        for part in (part.strip() for part in text.split(",")):
            value = part if parse is None else parse(part)  # its own ArgumentTypeError
            if (choices is not None and value not in choices) or (
                    about.check is not None and not about.check.accepts(value)):
                what = about.check.what if about.check is not None else "one of " + ", ".join(map(str, choices or ()))
                raise argparse.ArgumentTypeError(f"{part!r}: expected {what}")
            values.append(value)
        repeated = sorted({str(v) for v in values if values.count(v) > 1})
        if repeated:
            raise argparse.ArgumentTypeError(f"{repeated[0]} is given twice in {text!r}")
        return tuple(sorted(values)) if ascending else tuple(values)
    return read


def config_from_args(args: argparse.Namespace, config_class: type, **values: Any) -> Any:
    """A configuration from parsed options: every field with an option that :func:`add_options`
    added, then ``values`` (what the script sets itself: the command, the output folder...)."""
    found: dict[str, Any] = {}
    for item in fields(config_class):
        if item.name in values or not hasattr(args, item.name) or not setting_of(item).option(item.name):
            continue
        value = getattr(args, item.name)
        convert = setting_of(item).from_cli
        found[item.name] = value if convert is None else convert(value)
    return config_class(**found, **values)


