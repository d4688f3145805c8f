"""Circuits: named components, connections and exposed ports, nestable to any depth.

::

    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    node = c.add("node", VolumeNode(V=litre(0.5)))
    orf = c.add("orifice", Orifice(A=mm2(2)))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orf.a)
    c.connect(orf.b, tank.port)
    system = c.compile()

A circuit exposes inner ports with ``expose("P", inner_port)``; it can then be added to a bigger
circuit and connected like any component (``rig > pvg > pvb > compensator``).
"""

from __future__ import annotations

import re

from .component import Component, Port, PortRef
from .errors import CircuitError, ConnectionError_

__all__ = ["Circuit"]

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class Circuit:
    """A named collection of components and connections; itself usable as a component."""

    def __init__(self, name: str = "circuit"):
        self.name = name
        self._components: dict[str, Component | Circuit] = {}
        self._connections: list[tuple[PortRef, ...]] = []
        self._exposed: dict[str, tuple[PortRef, str]] = {}
        self._name: str | None = None
        self._parent: Circuit | None = None

    # building ----------------------------------------------------------------------------------
    def add(self, name: str, component):
        """Add ``component`` under ``name`` and return it."""
        if not isinstance(name, str) or not _NAME.match(name):
            raise CircuitError(f"circuit {self.path!r}: component name {name!r} is not a valid "
                               f"identifier (letters, digits, underscore; not starting with a "
                               f"digit)")
        if name in self._components:
            raise CircuitError(f"circuit {self.path!r} already has a component named {name!r}")
        if name in self._exposed:
            raise CircuitError(f"circuit {self.path!r}: {name!r} is already an exposed port")
        if not isinstance(component, (Component, Circuit)):
            raise CircuitError(f"circuit {self.path!r}: {name!r} must be a Component or Circuit, "
                               f"got {type(component).__name__}")
        if component._parent is not None:
            raise CircuitError(f"{type(component).__name__} {component.path!r} is already part of "
                               f"a circuit; create a new instance for {name!r}")
        if component is self:
            raise CircuitError(f"circuit {self.path!r} cannot contain itself")
        component._name = name
        component._parent = self
        self._components[name] = component
        return component

    def connect(self, *ports) -> None:
        """Join two or more ports into one connection set (a node)."""
        if len(ports) < 2:
            raise CircuitError(f"circuit {self.path!r}: connect() needs at least two ports, "
                               f"got {len(ports)}")
        refs = tuple(self._resolve(p) for p in ports)
        domains = {r.port.domain.name for r in refs}
        if len(domains) > 1:
            desc = ", ".join(f"{r.path()} ({r.port.domain.name})" for r in refs)
            raise ConnectionError_(
                f"circuit {self.path!r}: incompatible domains joined in one node: {desc}. A node "
                f"joins ports of one domain only; a hydraulic port meets a mechanical one through "
                f"a component that converts (e.g. PistonChamber or Cylinder).")
        self._connections.append(refs)

    def expose(self, name: str, inner, description: str = "") -> PortRef:
        """Make the inner port ``inner`` a port of this circuit called ``name``."""
        if not _NAME.match(name):
            raise CircuitError(f"circuit {self.path!r}: port name {name!r} is not an identifier")
        if name in self._exposed or name in self._components:
            raise CircuitError(f"circuit {self.path!r} already has a port or component {name!r}")
        ref = self._resolve(inner)
        self._exposed[name] = (ref, description)
        return PortRef(self, name)

    # access ------------------------------------------------------------------------------------
    @property
    def path(self) -> str:
        if self._parent is None:
            return self.name
        parent = self._parent.path if self._parent._parent is not None else None
        return f"{parent}.{self._name}" if parent else self._name

    @property
    def components(self) -> dict:
        """The direct subcomponents by name."""
        return dict(self._components)

    @property
    def ports(self) -> dict[str, Port]:
        """The exposed ports and their declarations."""
        return {name: ref.port for name, (ref, _) in self._exposed.items()}

    def __getitem__(self, path: str):
        import difflib
        node = self
        for part in path.split("."):
            if not isinstance(node, Circuit) or part not in node._components:
                pool = sorted(node._components) if isinstance(node, Circuit) else []
                close = difflib.get_close_matches(part, pool, n=1)
                hint = f" Did you mean {close[0]!r}?" if close else ""
                raise KeyError(f"circuit {self.path!r} has no component {path!r} ({part!r} is "
                               f"not in {node.path!r}, whose components are {pool}).{hint}")
            node = node._components[part]
        return node

    def __contains__(self, path: str) -> bool:
        try:
            self[path]
        except KeyError:
            return False
        return True

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        exposed = self.__dict__.get("_exposed", {})
        if name in exposed:
            return PortRef(self, name)
        comps = self.__dict__.get("_components", {})
        hint = (f" {name!r} is a component: use circuit[{name!r}]." if name in comps else "")
        raise AttributeError(f"circuit {self.__dict__.get('name')!r} has no port {name!r}; its "
                             f"ports are {sorted(exposed)}.{hint}")

    def _port_spec(self, name: str) -> Port:
        if name not in self._exposed:
            raise CircuitError(f"circuit {self.path!r} has no port {name!r}; its ports are "
                               f"{sorted(self._exposed)}")
        return self._exposed[name][0].port

    def _resolve(self, port) -> PortRef:
        """A PortRef from a PortRef or a dotted string ``"component.port"`` within this circuit."""
        if isinstance(port, str):
            comp_path, _, port_name = port.rpartition(".")
            if not comp_path:
                return PortRef(self, port_name) if port_name in self._exposed else \
                    self._fail_port(port)
            try:
                owner = self[comp_path]
            except KeyError as exc:
                raise CircuitError(str(exc.args[0])) from None
            owner._port_spec(port_name)
            return PortRef(owner, port_name)
        if not isinstance(port, PortRef):
            raise CircuitError(f"circuit {self.path!r}: connect() takes ports (component.port or "
                               f"'component.port' strings), got {type(port).__name__} "
                               f"{port!r}")
        port.port  # validates the port name
        if not self._owns(port.owner):
            raise CircuitError(f"port {port.path()!r} does not belong to circuit {self.path!r}; "
                               f"add its component to this circuit first")
        return port

    def _fail_port(self, text):
        raise CircuitError(f"circuit {self.path!r}: {text!r} does not name a port; write "
                           f"'component.port'")

    def _owns(self, owner) -> bool:
        node = owner
        while node is not None:
            if node is self:
                return True
            node = node._parent
        return False

    # compiling ---------------------------------------------------------------------------------
    def compile(self, **options):
        """Compile to a :class:`~pvgraph.system.System` (see :func:`pvgraph.compiler.compile`)."""
        from .compiler import compile_circuit
        return compile_circuit(self, **options)

    def __repr__(self):
        return f"<Circuit {self.path} with {len(self._components)} components>"
