"""How a setting is declared and checked.

A setting is a field of a frozen configuration dataclass declared with :func:`setting`: its
name and type are the field's, and its :class:`Setting` says the rest (default, help text,
its ``settings.checks.Check``, whether it changes the results, its command-line option). Every configuration of
the project declares its fields this way (``settings.experiment.ExperimentConfig``,
``settings.world.WorldOverrides``, ``contention.config.ContentionConfig``, the sweeps'
``runs.sweep_config``); a configuration that means the same thing as another's field takes
that declaration with :func:`same_as` instead of writing it again.

Derived here, for any such configuration: the checks (:func:`check_config`), a configuration
from a Python API's keyword arguments (:func:`config_from_keywords`) and the settings a run
changed (:func:`changed_settings`). The command line derived from the same declarations is
``settings.options``'s.

Only light modules here: the scripts build their parsers from these before NumPy, pandas, simpy
or TensorFlow load (``tests/test_first_answer.py``).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from yafs_safetail.settings.checks import Check


class SettingError(ValueError):
    """A bad setting (one line naming its option or field, what it accepts and the value)."""

class Provided:
    """A conversion a setting declared on this floor needs and a higher floor provides when its
    package is imported (``settings.experiment.USER_METHODS``: the ``methods`` package turns
    ``--method`` specs into users' policies), so that the declaration imports nothing above it.
    Called before it is provided, it says which package provides it."""

    def __init__(self, what: str, provider: str) -> None:
        self.what, self.provider = what, provider
        self._convert: Callable[[Any], Any] | None = None

    def provide(self, convert: Callable[[Any], Any]) -> None:
        """Set the conversion (the providing package does, once, as it is imported)."""
        self._convert = convert

    def __call__(self, value: Any) -> Any:
        if self._convert is None:
            raise RuntimeError(f"{self.what}: nothing provides the conversion; import {self.provider} first")
        return self._convert(value)



# ----------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class Setting:
    """What the project knows about one field of a configuration.

    Attributes:
        help: what it means, as the command line's help shows it.
        changes_results: whether two runs differing in it may write different results files
            (part of the run id). Where and how a run goes (its folder, processes, progress,
            resuming) does not.
        check: the values it accepts (None: any value of its type).
        flag: its command-line option; None: ``--`` and the name with dashes. ``""``: none
            (set from Python or a grid only).
        optional: None is a valid value (the preset's or the world's own).
        action: an argparse action instead of a typed value (``"store_true"``, ``"store_false"``
            for a ``--no-...`` flag, ``"append"``).
        metavar: the option's value placeholder in the help.
        from_cli: turns the parsed value into the field's value (e.g. specs into methods).
        in_grid: a campaign grid may set it although it does not change the results (which
            copies of the figures a run draws); it stays out of the run id.
        negation: for a flag (``store_true``), an option that says its default explicitly, the
            two mutually exclusive (kept for scripts that passed it).
        deprecated: older spellings of its option that still work, each saying on stderr that it
            is deprecated and which option replaces it (kept only while documented commands of
            earlier versions may use them).
    """

    help: str
    changes_results: bool = True
    check: Check | None = None
    flag: str | None = None
    optional: bool = False
    action: str | None = None
    metavar: str | None = None
    from_cli: Callable[[Any], Any] | None = None
    in_grid: bool = False
    negation: str | None = None
    deprecated: tuple[str, ...] = ()

    def option(self, name: str) -> str:
        """The command-line option of the field ``name`` (``--steps-scale``), or ``""``."""
        return f"--{name.replace('_', '-')}" if self.flag is None else self.flag

    def label(self, name: str, style: str) -> str:
        """How an error names the field ``name``: its option in the ``"option"`` style (when it
        has one), else the field's own name (the ``"field"`` style, for Python APIs)."""
        return (self.option(name) or name) if style == "option" else name


_SETTING = "yafs_safetail.setting"


class _Required:
    """The default of a setting that has none (:data:`REQUIRED`)."""

    def __repr__(self) -> str:
        return "REQUIRED"


#: A setting's default when every instance must give it (a learner's hyperparameters, say).
REQUIRED: Any = _Required()


def setting(default: Any, help: str, **kwargs: Any) -> Any:
    """A dataclass field with its :class:`Setting` (``kwargs`` are the Setting's); ``default``
    :data:`REQUIRED`: a field without a default."""
    about = {_SETTING: Setting(help=help, **kwargs)}
    return field(metadata=about) if default is REQUIRED else field(default=default, metadata=about)


def same_as(config_class: type, name: str, default: Any = dataclasses.MISSING, **changes: Any) -> Any:
    """A field declared as ``config_class``'s field ``name`` is: the same setting in another
    configuration (``ContentionConfig.use_case`` is ``Task.use_case``), so its help, check and
    option are written once. The type annotation is restated for the type checker.

    Args:
        config_class: the configuration that declares the setting.
        name: its field there.
        default: this configuration's default, when it differs (e.g. None where the other
            configuration has a file; :data:`REQUIRED`: none).
        changes: :class:`Setting` attributes that differ here (``flag=""``: no option).
    """
    item = field_of(config_class, name)
    about = dataclasses.replace(setting_of(item), **changes)
    if default is REQUIRED:
        return field(metadata={_SETTING: about})
    return field(default=item.default if default is dataclasses.MISSING else default, metadata={_SETTING: about})


def field_of(config_class: type, name: str) -> dataclasses.Field[Any]:
    """The field ``name`` of a configuration class (TypeError: it has none)."""
    for item in fields(config_class):
        if item.name == name:
            return item
    raise TypeError(f"{config_class.__name__} has no field {name!r}")


def setting_of(item: dataclasses.Field[Any]) -> Setting:
    """The :class:`Setting` of a configuration field."""
    found = item.metadata.get(_SETTING)
    if not isinstance(found, Setting):
        raise TypeError(f"{item.name}: a configuration field must be declared with setting()")
    return found


def has_setting(item: dataclasses.Field[Any]) -> bool:
    """Whether a configuration field was declared with :func:`setting`."""
    return isinstance(item.metadata.get(_SETTING), Setting)


def changed_settings(config: Any, skip: Sequence[str] = ()) -> tuple[str, ...]:
    """The settings of ``config`` that change results and were set away from their defaults, as
    the options that set them (``--failure-probability 0.2``, ``--topology mesh.json``): what a
    run's figure titles and report heading add to its use case, preset and seed (``skip``).

    Files are named by their file name; a setting left at its default is never listed, so a
    run with none set says nothing more than before.
    """
    changed: list[str] = []
    for item in dataclasses.fields(config):
        if not has_setting(item) or item.name in skip:
            continue
        about = setting_of(item)
        if not about.changes_results:
            continue
        default = item.default if item.default is not dataclasses.MISSING else (
            item.default_factory() if item.default_factory is not dataclasses.MISSING else dataclasses.MISSING)
        value = getattr(config, item.name)
        if value == default:
            continue
        option = about.option(item.name) or item.name
        if isinstance(value, bool):
            changed.append(option)
            continue
        shown = shown_value(value)
        changed.append(f"{option} {shown}")
    return tuple(changed)


def shown_value(value: Any) -> str:
    """A setting's value as a title shows it: the same text for the same value in any run
    (file names without their folders; a user's method by its spec; never an object's repr)."""
    if isinstance(value, Path):
        return value.name
    if isinstance(value, tuple | list):
        return ",".join(shown_value(item) for item in value)
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, str | int):
        return str(value)
    spec = getattr(value, "spec", None)  # a user's --method NAME=path/file.py:Class
    if isinstance(spec, str):
        return re.sub(r"[^=:]*/", "", spec)
    return type(value).__name__


# ----------------------------------------------------------------------------- checking


def check_config(config: Any, style: str = "option") -> None:
    """Check every field of a configuration against its :class:`Setting`.

    Args:
        config: a dataclass whose fields were declared with :func:`setting`.
        style: how errors name a field: ``"option"`` (``--steps-scale``, for runs) or
            ``"field"`` (``steps_scale``, for Python APIs such as the Gymnasium environment).

    Raises:
        SettingError: the first bad field (one line: its name, what it accepts, its value), as
            the configuration's own error class (its ``setting_error``) when it has one.
    """
    error: type[ValueError] = getattr(type(config), "setting_error", SettingError)
    name = refused_field(config)
    if name is not None:
        about = setting_of(field_of(type(config), name))
        assert about.check is not None
        raise error(f"{about.label(name, style)}: expected {about.check.what}, got {getattr(config, name)!r}")


def refused_field(config: Any) -> str | None:
    """The first field of ``config`` (a dataclass declared with :func:`setting`) whose value its
    declared check refuses, or None: the checks themselves, for a configuration that words its
    own error (``settings.world.WorldSettings``, ``methods.safetail.presets.LearnerConfig``)."""
    for item in fields(config):
        if not has_setting(item):  # a part checked on its own (a sweep's base world)
            continue
        about = setting_of(item)
        value = getattr(config, item.name)
        if about.check is None or (value is None and about.optional):
            continue
        if not about.check.accepts(value):
            return item.name
    return None


def keyword_names(*groups: type) -> tuple[str, ...]:
    """Every field of ``groups``, in order: the keyword arguments a Python API derives from them."""
    return tuple(item.name for group in groups for item in fields(group))


def config_from_keywords(config_class: type, keywords: Mapping[str, Any], allowed: Sequence[str],
                         what: str, **values: Any) -> Any:
    """A configuration from a Python API's keyword arguments (a Gymnasium environment's).

    Paths may be given as text, as everywhere in Python; an unknown keyword is a one-line
    :class:`SettingError` naming it and ``what`` takes.

    Args:
        config_class: the configuration.
        keywords: the caller's keywords.
        allowed: the fields the API takes.
        what: the API, for the error (``"SafeTail-v0"``).
        values: fields the API sets itself.
    """
    unknown = sorted(set(keywords) - set(allowed))
    if unknown:
        raise SettingError(f"{unknown[0]}: not a setting of {what} (its settings: {', '.join(allowed)})")
    typed = dict(keywords)
    for item in fields(config_class):
        if item.name in typed and item.type in ("Path", "Path | None") and isinstance(typed[item.name], str):
            typed[item.name] = Path(typed[item.name])
    return config_class(**typed, **values)
