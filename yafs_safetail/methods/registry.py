"""The one list of method names: how a name becomes a policy, and the order results use.

Names: ``SafeTail``, ``Oracle``, ``Rand-x``, ``MinLoad-x``, ``MinProp-x`` (x = the redundancy
level), ``Hedge`` and ``Tied`` (contention world only), and a user's own policy loaded from ``path/to/file.py:ClassName`` or
``package.module:ClassName`` (optionally ``NAME=...`` to name it in results).

Which methods learn: SafeTail, and a user's policy whose class is a
:class:`~yafs_safetail.methods.learning.LearningPolicy` (:attr:`UserMethod.learns`); a run gives
each of them a training phase, checkpoints and ``--resume`` (``runs.training``).
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import sys
import zlib
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from yafs_safetail.defaults import SAFETAIL as SAFETAIL
from yafs_safetail.edge.observation import Observation
from yafs_safetail.methods.baselines import MinLoadX, MinPropX, Oracle, RandX, candidates_of
from yafs_safetail.methods.hedging import Hedge, Tied
from yafs_safetail.methods.learning import TRAIN_PHASE, LearningPolicy
from yafs_safetail.methods.policy import (
    DispatchSupport,
    Policy,
    PolicyError,
    check_dispatch,
    choice_problem,
    raised_where,
)

ORACLE = "Oracle"
#: The redundancy-level families of §V-B, in report order, and their policies.
BASELINE_FAMILIES: tuple[str, ...] = ("Rand", "MinLoad", "MinProp")
_FAMILY_POLICIES: dict[str, Callable[..., Policy]] = {"Rand": RandX, "MinLoad": MinLoadX, "MinProp": MinPropX}
#: The Tail at Scale's requests (``methods.hedging``): they need the contention world.
CONTENTION_BASELINES: dict[str, Callable[..., Policy]] = {"Hedge": Hedge, "Tied": Tied}
_BASELINE_RE = re.compile(r"^(Rand|MinLoad|MinProp)-(\d+)$")


def method_rng(seed: int, method: str) -> np.random.Generator:
    """A method's own generator (Rand draws, MinLoad tie-breaks), independent per method: the same
    for a method whichever world runs it (the experiment's workers, the contention sweep)."""
    return np.random.default_rng(np.random.SeedSequence([seed, zlib.crc32(method.encode())]))


def parse_method(name: str) -> tuple[str, int | None]:
    """Split a method name into its family and redundancy level.

    Returns:
        ``(family, x)``: ``("Rand", 2)`` for "Rand-2"; ``(name, None)`` for methods without a
        level (SafeTail, Oracle, anything else).
    """
    match = _BASELINE_RE.match(name)
    if match:
        return match.group(1), int(match.group(2))
    return name, None


def method_sort_key(name: str) -> tuple[int, str, int]:
    """Sort key giving SafeTail, Oracle, Rand-x, MinLoad-x, MinProp-x (x ascending), Hedge,
    Tied, others."""
    family, level = parse_method(name)
    if name == SAFETAIL:
        return (0, "", 0)
    if name == ORACLE:
        return (1, "", 0)
    if family in BASELINE_FAMILIES and level is not None:
        return (2 + BASELINE_FAMILIES.index(family), "", level)
    if name in CONTENTION_BASELINES:
        return (2 + len(BASELINE_FAMILIES), "", list(CONTENTION_BASELINES).index(name))
    return (3 + len(BASELINE_FAMILIES), name, 0)


def sort_methods(names: Iterable[str]) -> list[str]:
    """Distinct method names in report order (see :func:`method_sort_key`)."""
    return sorted(set(names), key=method_sort_key)


def baselines_of(names: Iterable[str], family: str | None = None) -> list[str]:
    """The Rand/MinLoad/MinProp methods among ``names`` (one family if given), report order."""
    out = []
    for name in sort_methods(names):
        fam, level = parse_method(name)
        if fam in BASELINE_FAMILIES and level is not None and family in (None, fam):
            out.append(name)
    return out


def baseline_names(redundancy_levels: Sequence[int]) -> list[str]:
    """Oracle, then Rand-x, MinLoad-x, MinProp-x for every x."""
    names = [ORACLE]
    for family in BASELINE_FAMILIES:
        names += [f"{family}-{x}" for x in redundancy_levels]
    return names


def make_baseline(name: str, n_servers: int, rng: np.random.Generator,
                  reading: str = "paper-text") -> Policy:
    """A baseline from its name: ``"Oracle"``, ``"Rand-x"``, ``"MinLoad-x"``, ``"MinProp-x"``,
    ``"Hedge"``, ``"Tied"``; ``reading`` is MinLoad-x's and MinProp-x's (``BASELINE_READINGS``,
    docs/calibration.md rule 5: the world's ``baseline_reading``).

    Raises:
        PolicyError: an unknown name or reading, or x outside 1..n.
    """
    family, level = parse_method(name)
    if name == ORACLE:
        return Oracle(n_servers, rng)
    if name in CONTENTION_BASELINES:
        return CONTENTION_BASELINES[name](n_servers, rng)
    if level is None:
        raise PolicyError(
            f"method: unknown baseline {name!r}; expected Oracle, Rand-x, MinLoad-x, MinProp-x, "
            "Hedge or Tied"
        )
    if family in ("MinLoad", "MinProp"):
        return _FAMILY_POLICIES[family](n_servers, rng, level, candidates_of(reading, level, n_servers))
    return _FAMILY_POLICIES[family](n_servers, rng, level)


def _load_class(spec: str) -> type[Policy]:
    source, _, class_name = spec.rpartition(":")
    if not source or not class_name:
        raise PolicyError(f"--method {spec}: expected path/to/file.py:ClassName or module:ClassName")
    if source.endswith(".py") or "/" in source or "\\" in source:
        path = Path(source)
        if not path.is_file():
            raise PolicyError(f"--method {spec}: {path}: no such file")
        module_name = f"yafs_safetail_user_policy_{path.stem}"
        module_spec = importlib.util.spec_from_file_location(module_name, path)
        if module_spec is None or module_spec.loader is None:
            raise PolicyError(f"--method {spec}: {path}: not a Python file")
        module = importlib.util.module_from_spec(module_spec)
        sys.modules[module_name] = module
        try:
            module_spec.loader.exec_module(module)
        except Exception as error:
            raise PolicyError(f"--method {spec}: {path} failed to import: "
                              f"{type(error).__name__}: {error}") from None
    else:
        try:
            module = importlib.import_module(source)
        except ImportError as error:
            raise PolicyError(f"--method {spec}: cannot import {source!r}: {error}") from None
    policy_class = getattr(module, class_name, None)
    if not (isinstance(policy_class, type) and issubclass(policy_class, Policy)):
        raise PolicyError(f"--method {spec}: {class_name!r} is not a Policy subclass in {source}")
    return policy_class


class UserMethod:
    """A user's policy named on the command line: ``[NAME=]path/file.py:Class`` or
    ``[NAME=]module:Class``. Its class is loaded (and checked) when the spec is parsed."""

    def __init__(self, spec: str) -> None:
        name, sep, target = spec.partition("=")
        if not sep or ":" in name or "/" in name:  # no NAME= prefix
            name, target = "", spec
        self.spec = spec
        self.policy_class = _load_class(target)
        self.name = name or self.policy_class.name or self.policy_class.__name__
        if self.name in (SAFETAIL, ORACLE) or parse_method(self.name)[1] is not None:
            raise PolicyError(f"--method {spec}: the name {self.name!r} is taken by a built-in method")

    def make(self, n_servers: int, rng: np.random.Generator) -> Policy:
        """A fresh instance, named as on the command line."""
        try:
            policy = self.policy_class(n_servers, rng)
        except TypeError as error:
            raise PolicyError(f"--method {self.spec}: cannot construct {self.policy_class.__name__}"
                              f"(n_servers, rng): {error}") from None
        except Exception as error:  # a bug in the user's constructor: one line, where it is
            raise PolicyError(f"--method {self.spec}: {self.policy_class.__name__}(n_servers, rng) "
                              f"raised {raised_where(error, self.policy_class)}") from None
        policy.name = self.name
        return policy

    def check_first_choice(self, n_servers: int, rng: np.random.Generator,
                           observation: Observation, support: DispatchSupport,
                           first: str = "the run's first request") -> None:
        """Build a throwaway instance and ask it for one request's servers, before the run.

        A policy that cannot choose (it returns nothing, a server that does not exist, a server
        twice, something that is not server indices, or it raises) would otherwise be found
        only when its simulation starts, after SafeTail's training. The instance is not the one
        the run uses, so the run's own policy draws from ``rng``'s twin exactly as without this
        check; a learner is put in its training phase first, as the run does.

        Args:
            n_servers: the run's servers.
            rng: a generator for the throwaway instance (not the run's instance's).
            observation: ω^t of the run's first request; the policy may keep or change it, so
                it must not share arrays with the run's world.
            support: the dispatch modes the run's world runs (:func:`check_dispatch`).
            first: which request ``observation`` is, as the error says it (a sweep's: "the
                sweep's first request").

        Raises:
            PolicyError: one line naming the policy's file and class and what is wrong.
        """
        policy = self.make(n_servers, rng)
        where = f"--method {self.spec}"
        try:
            check_dispatch(policy, support)
        except PolicyError as error:  # (its message starts with the method's name)
            raise PolicyError(f"{where}: {str(error).removeprefix(f'{policy.name}: ')}") from None
        if isinstance(policy, LearningPolicy):
            policy.begin_phase(TRAIN_PHASE)
        asked = f"{where}: on {first}, {self.policy_class.__name__}.choose()"
        try:
            chosen = policy.choose(observation if policy.observes else None)
        except Exception as error:
            raise PolicyError(f"{asked} raised {raised_where(error, self.policy_class)}") from None
        _, problem = choice_problem(chosen, n_servers)
        if problem:
            raise PolicyError(f"{asked} returned {chosen!r}: {problem}")

    @property
    def learns(self) -> bool:
        """Whether the policy learns (a LearningPolicy): a run then trains it before testing."""
        return issubclass(self.policy_class, LearningPolicy)

    def make_learner(self, n_servers: int, rng: np.random.Generator) -> LearningPolicy:
        """A fresh instance of a policy that :attr:`learns`, named as on the command line."""
        policy = self.make(n_servers, rng)
        if not isinstance(policy, LearningPolicy):
            raise PolicyError(f"--method {self.spec}: {self.policy_class.__name__} is not a LearningPolicy")
        return policy
