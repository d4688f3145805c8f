"""Where applications built on pvgraph register their circuits, commands and plots.

The framework knows no application. A package of circuits (the PVG 32 in ``circuits/``, a
user's machine library) makes its circuits known to the command line and to other tools by
registering them from above::

    # mypackage/pvgraph_plugin.py
    def register(registry):
        registry.circuit("press", build_press, description="the 40 t press",
                         variables=["cyl.A.p", "cyl.flange.x"], t_end=5.0)

and declaring the function in its ``pyproject.toml``::

    [project.entry-points."pvgraph.circuits"]
    mypackage = "mypackage.pvgraph_plugin:register"

Registration functions run once, on the first lookup. Without installing a package, the
environment variable ``PVGRAPH_PLUGINS`` names them too, comma separated
(``PVGRAPH_PLUGINS=mypackage.pvgraph_plugin:register``; ``:register`` may be left out).

What can be registered:

- **circuits** (:meth:`Registry.circuit`): a name, a ``build(**options) -> Circuit``, the
  variables ``pvgraph simulate`` reports by default, its end time and the keyword options the
  builder takes. The CLI then takes the name wherever it takes ``file.py:build``.
- **commands** (:meth:`Registry.command`): a whole subcommand (``pvgraph validate``).
- **extensions** (:meth:`Registry.extension`) of a built-in command: extra options on
  ``simulate``, ``sweep`` or ``linearize``, the builder options they give, and a ``run(args)``
  that handles the command when it is given no circuit target (``pvgraph sweep --scenario``).
- **plots** (:meth:`Registry.plot`): named figure functions other tools may look up.
"""

from __future__ import annotations

import importlib
import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

from .errors import PvgraphError

__all__ = ["ENTRY_POINT_GROUP", "ENV_VAR", "ENTRY_POINTS_VAR", "CircuitEntry", "CommandEntry", "Extension",
           "Registry", "registry", "RegistryError"]

ENTRY_POINT_GROUP = "pvgraph.circuits"
ENV_VAR = "PVGRAPH_PLUGINS"
#: set to "0" to skip the installed entry points (only PVGRAPH_PLUGINS is read then)
ENTRY_POINTS_VAR = "PVGRAPH_ENTRY_POINTS"


class RegistryError(PvgraphError):
    """A registration is malformed, clashes with another, or a plugin cannot be loaded."""


@dataclass(frozen=True)
class CircuitEntry:
    """A registered circuit: ``build(**options)`` returns a fresh :class:`~pvgraph.Circuit`."""

    name: str
    build: Callable[..., Any]
    description: str = ""
    variables: tuple[str, ...] = ()
    t_end: float | None = None
    options: tuple[str, ...] = ()
    group: str = ""


@dataclass(frozen=True)
class CommandEntry:
    """A registered subcommand: ``configure(parser)`` adds its options, ``run(args)`` runs it."""

    name: str
    help: str
    configure: Callable[[Any], None]
    run: Callable[[Any], int]
    description: str = ""


@dataclass(frozen=True)
class Extension:
    """Options an application adds to a built-in command (``simulate``, ``sweep``, ...).

    ``configure(parser)`` adds the options; ``options(args)`` returns the keyword options they
    pass to a registered circuit's builder; ``run(args)`` handles the command when no circuit
    target is given.
    """

    command: str
    configure: Callable[[Any], None]
    options: Callable[[Any], dict] | None = None
    run: Callable[[Any], int] | None = None


@dataclass
class Registry:
    """Circuits, commands, command extensions and plots registered by applications."""

    circuits: dict[str, CircuitEntry] = field(default_factory=dict)
    commands: dict[str, CommandEntry] = field(default_factory=dict)
    extensions: dict[str, list[Extension]] = field(default_factory=dict)
    plots: dict[str, Callable] = field(default_factory=dict)
    _loaded: bool = False
    _loading: bool = False

    # registering ---------------------------------------------------------------------------
    def circuit(self, name: str, build: Callable[..., Any], *, description: str = "",
                variables=(), t_end: float | None = None, options=(), group: str = "") -> None:
        """Register ``build(**options) -> Circuit`` under ``name``."""
        self._check_name(name, self.circuits, "circuit")
        if not callable(build):
            raise RegistryError(f"circuit {name!r}: build must be callable, got "
                                f"{type(build).__name__}")
        self.circuits[name] = CircuitEntry(name, build, description, tuple(variables), t_end,
                                           tuple(options), group)

    def command(self, name: str, configure: Callable, run: Callable, *, help: str = "",
                description: str = "") -> None:
        """Register a subcommand ``pvgraph NAME``."""
        self._check_name(name, self.commands, "command")
        self.commands[name] = CommandEntry(name, help, configure, run, description)

    def extension(self, command: str, configure: Callable, *, options: Callable | None = None,
                  run: Callable | None = None) -> None:
        """Add options to the built-in ``command`` (see :class:`Extension`)."""
        runners = [e for e in self.extensions.get(command, []) if e.run is not None]
        if run is not None and runners:
            raise RegistryError(f"command {command!r} already has a handler for runs without "
                                f"a circuit target")
        self.extensions.setdefault(command, []).append(Extension(command, configure, options,
                                                                 run))

    def plot(self, name: str, function: Callable) -> None:
        """Register a figure function under ``name``."""
        self._check_name(name, self.plots, "plot")
        self.plots[name] = function

    @staticmethod
    def _check_name(name, table, what):
        if not isinstance(name, str) or not name.strip() or name != name.strip():
            raise RegistryError(f"{what} name {name!r} must be a non-empty string without "
                                f"surrounding spaces")
        if name in table:
            raise RegistryError(f"a {what} named {name!r} is already registered")

    # loading --------------------------------------------------------------------------------
    def load(self) -> "Registry":
        """Run every registration function (entry points, then ``PVGRAPH_PLUGINS``), once."""
        if self._loaded or self._loading:
            return self
        self._loading = True
        try:
            for label, func in _plugin_functions():
                try:
                    func(self)
                except RegistryError:
                    raise
                except Exception as exc:
                    warnings.warn(f"pvgraph plugin {label} failed to register: "
                                  f"{type(exc).__name__}: {exc}", stacklevel=2)
        finally:
            self._loading = False
        self._loaded = True
        return self

    def reset(self) -> None:
        """Forget everything registered (tests)."""
        self.circuits.clear()
        self.commands.clear()
        self.extensions.clear()
        self.plots.clear()
        self._loaded = False


def _plugin_functions():
    """``(label, register function)`` of every installed entry point and ``PVGRAPH_PLUGINS``."""
    from importlib.metadata import entry_points

    found = []
    seen = set()
    installed = entry_points(group=ENTRY_POINT_GROUP) \
        if os.environ.get(ENTRY_POINTS_VAR, "1").strip() != "0" else ()
    for ep in installed:
        if ep.value in seen:
            continue
        seen.add(ep.value)
        try:
            found.append((f"{ep.name} ({ep.value})", ep.load()))
        except Exception as exc:
            warnings.warn(f"pvgraph plugin {ep.name} ({ep.value}) cannot be imported: "
                          f"{type(exc).__name__}: {exc}", stacklevel=3)
    for spec in filter(None, (s.strip() for s in os.environ.get(ENV_VAR, "").split(","))):
        module, _, attr = spec.partition(":")
        value = f"{module}:{attr or 'register'}"
        if value in seen:
            continue
        seen.add(value)
        try:
            found.append((spec, getattr(importlib.import_module(module), attr or "register")))
        except (ImportError, AttributeError) as exc:
            raise RegistryError(f"{ENV_VAR} names {spec!r}, which cannot be loaded: "
                                f"{type(exc).__name__}: {exc}") from None
    return found


#: the registry the command line and the tools read
registry = Registry()
