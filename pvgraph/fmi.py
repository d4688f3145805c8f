"""Export a circuit as an FMI 2.0 co-simulation FMU, for Simulink, Dymola, OpenModelica, ...

::

    from pvgraph.fmi import export_fmu
    export_fmu(build_rig(), "pvg32_rig.fmu", inputs=["U_input.k"],
               outputs=["load.f.port.p", "pvg.pvb.main_spool.flange.x"],
               parameters=["pump.Q0"])

or ``pvgraph export TARGET --out rig.fmu --var NAME ...`` (outputs only).

- **Inputs** are parameters the user marks (``component.field``, typically the value of a
  source: a ``Constant``'s ``k``, a ``FlowSource``'s ``Q``); the importing tool sets them
  between communication steps. **Outputs** are variables or derived outputs by dotted name.
  **Parameters** are further ``component.field`` values the importing tool may set before
  the run starts. All values are SI, each variable with its unit in the model description
  (``unit="Pa"``, defined under ``UnitDefinitions`` by its exponents of the SI base units).
- **Packaging.** The FMU is built with `pythonfmu <https://github.com/NTNU-IHB/PythonFMU>`_:
  its binary (Linux x86-64 and Windows x86-64) starts a Python interpreter that runs a small
  slave class; the circuit travels inside the FMU as a model file
  (:mod:`pvgraph.modelfile`, ``resources/model.toml``), so only library components can be
  exported. Each communication step continues the simulation with pvgraph's solver from the
  state the previous step ended in; a changed input rebuilds the system (about 0.1 s for the
  PVG 32 rig) and carries the state over by name.
- **What the importing machine needs**: a 64-bit Python 3 on the library path (the one
  ``libpython3.x`` the FMU's binary finds; on Linux the interpreter's shared library, on
  Windows ``python3x.dll`` on ``PATH``), with ``pythonfmu``, ``pvgraph`` (and so numpy,
  scipy, networkx, pydantic) installed: ``pip install "pvgraph[fmi]"``. The FMU does not
  embed Python or pvgraph.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from typing import Sequence

from .errors import PvgraphError

__all__ = ["export_fmu", "CircuitSlave", "FmiError"]

RTOL = 1e-6
MODEL_FILE = "model.toml"
SPEC_FILE = "pvgraph_fmu.json"


class FmiError(PvgraphError):
    """An FMU cannot be exported (unknown names, a component outside the library, no pythonfmu)."""


class CircuitSlave:
    """The running model inside the FMU: a circuit stepped from one communication point to the
    next, with inputs and parameters applied by dotted ``component.field`` name."""

    def __init__(self, model_path: str, spec: dict):
        from .modelfile import load
        self.circuit = load(model_path)
        self.spec = spec
        known = self.circuit.parameters()
        self.values = {n: float(known[n][0]) for n in spec["inputs"] + spec["parameters"]}
        self._applied = dict(self.values)
        self.rtol = float(spec.get("rtol", RTOL))
        self.system = self.circuit.compile()
        self.t = 0.0
        self._started = False
        self.y = self.system.y0.copy()
        self.yp = self.system.yp0.copy()
        self._outputs = self._evaluate(self.t, self.y, self.yp)

    def _evaluate(self, t, y, yp) -> dict:
        import numpy as np
        out = {}
        observed = None
        for name in self.spec["outputs"]:
            if name in self.system.observed:
                if observed is None:
                    modes = np.asarray([self.system.modes], dtype=float)
                    observed = self.system.evaluate_observed(
                        np.asarray([t]), y[None, :], yp[None, :], modes)
                out[name] = float(observed[name][0])
            else:
                coef, idx, off = self.system.resolve(name)
                out[name] = off if idx is None else coef * float(y[idx]) + off
        return out

    def get(self, name: str) -> float:
        if name in self._outputs:
            if not self._started and self._pending():
                # outputs read before the first step show the parameters set so far
                self._apply()
                self._outputs = self._evaluate(self.t, self.y, self.yp)
            return self._outputs[name]
        return self.values[name]

    def set(self, name: str, value: float) -> None:
        value = float(value)
        # a value the component refuses is refused here, naming it, not at the next step
        self.circuit.check_parameters({name: value})
        self.values[name] = value

    def _pending(self) -> dict:
        return {k: v for k, v in self.values.items() if self._applied.get(k) != v}

    def _apply(self) -> None:
        changed = self._pending()
        if not changed:
            return
        old_names, old_y, old_yp = list(self.system.names), self.y, self.yp
        self.circuit.set_parameters(changed)
        # runtime parameters: no compilation (a structural one recompiles, with a warning)
        self.system = self.system.with_params(changed)
        self.y = self.system.y0.copy()
        self.yp = self.system.yp0.copy()
        if self._started:       # before the run, start values follow the parameters (p0)
            position = {n: k for k, n in enumerate(old_names)}
            for k, n in enumerate(self.system.names):
                if n in position:
                    self.y[k] = old_y[position[n]]
                    self.yp[k] = old_yp[position[n]]
        self._applied = dict(self.values)

    def step(self, t: float, dt: float) -> bool:
        from .simulate import simulate
        self._apply()
        self._started = True
        sol = simulate(self.system, t + dt, t_start=t, rtol=self.rtol, y0=self.y, yp0=self.yp,
                       t_eval=[t, t + dt])
        self.y, self.yp, self.t = sol.y[-1].copy(), sol.yp[-1].copy(), t + dt
        self._outputs = self._evaluate(self.t, self.y, self.yp)
        return True


_SLAVE = '''"""FMU slave generated by pvgraph.fmi: the circuit in resources/{model}, run by pvgraph."""

import json
import os

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

from pvgraph.fmi import CircuitSlave


class {cls}(Fmi2Slave):

    author = "pvgraph"
    description = {description!r}

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        with open(os.path.join(self.resources, "{spec}")) as f:
            spec = json.load(f)
        self._spec = spec
        self._model = CircuitSlave(os.path.join(self.resources, "{model}"), spec)
        for name in spec["inputs"]:
            self._real(name, Fmi2Causality.input, Fmi2Variability.continuous, True)
        for name in spec["parameters"]:
            self._real(name, Fmi2Causality.parameter, Fmi2Variability.fixed, True)
        for name in spec["outputs"]:
            self._real(name, Fmi2Causality.output, Fmi2Variability.continuous, False)

    def _real(self, name, causality, variability, settable):
        model = self._model
        setter = (lambda v, n=name: model.set(n, v)) if settable else None
        self.register_variable(Real(name, causality=causality, variability=variability,
                                    getter=lambda n=name: model.get(n), setter=setter),
                               nested=False)

    def to_xml(self, model_options=dict()):
        # FMI 2.0 lists the outputs computed at initialisation under InitialUnknowns too
        from xml.etree.ElementTree import Element, SubElement
        root = super().to_xml(model_options)
        # each variable's unit (SI), defined once under UnitDefinitions by its exponents of
        # the SI base units, so that an importing tool converts and checks them
        units = self._spec.get("units", {{}})
        for var in root.iter("ScalarVariable"):
            unit = units.get(var.get("name"))
            real = var.find("Real")
            if unit and real is not None:
                real.set("unit", unit)
        defs = self._spec.get("unit_definitions", {{}})
        if defs:
            table = Element("UnitDefinitions")
            for unit, base in sorted(defs.items()):
                SubElement(SubElement(table, "Unit", name=unit), "BaseUnit",
                           attrib={{k: str(v) for k, v in base.items()}})
            # after ModelExchange and CoSimulation, before the rest (the schema's order)
            at = sum(1 for child in root if child.tag in ("ModelExchange", "CoSimulation"))
            root.insert(at, table)
        structure = root.find("ModelStructure")
        outputs = structure.find("Outputs")
        if outputs is not None:
            initial = SubElement(structure, "InitialUnknowns")
            for unknown in outputs:
                SubElement(initial, "Unknown", attrib=dict(unknown.attrib))
        return root

    def do_step(self, current_time, step_size):
        return self._model.step(current_time, step_size)
'''


def export_fmu(circuit, path, *, inputs: Sequence[str] = (), outputs: Sequence[str] = (),
               parameters: Sequence[str] = (), rtol: float = RTOL,
               description: str | None = None) -> str:
    """Write ``circuit`` as an FMI 2.0 co-simulation FMU to ``path``; returns the path.

    Parameters
    ----------
    circuit : Circuit
        Built from library components (it travels as a model file).
    inputs, parameters : list of str
        ``component.field`` parameters: inputs are set at any communication point, parameters
        before the run.
    outputs : list of str
        Variables or derived outputs (see ``pvgraph vars``).
    rtol : float
        Relative tolerance of pvgraph's solver inside the FMU.
    """
    try:
        from pythonfmu import FmuBuilder
    except ImportError:
        raise FmiError('FMU export needs pythonfmu: pip install "pvgraph[fmi]"') from None
    from .modelfile import ModelFileError, loads, dumps

    from .simulate import _name_list
    inputs = _name_list(inputs, "export_fmu: inputs")
    outputs = _name_list(outputs, "export_fmu: outputs")
    parameters = _name_list(parameters, "export_fmu: parameters")
    path = os.fspath(path)
    if not path.endswith(".fmu"):
        raise FmiError(f"{path}: an FMU file name ends in .fmu")
    if not outputs:
        raise FmiError("export_fmu needs at least one output variable")
    known = circuit.parameters()
    for name in list(inputs) + list(parameters):
        if name not in known:
            circuit._parameter_owner(name)          # raises with close matches
        if not isinstance(known[name][0], (int, float)) or isinstance(known[name][0], bool):
            raise FmiError(f"{name} is not a real-valued parameter ({known[name][0]!r})")
    # an FMU names each variable once (FMI 2.0: unique ScalarVariable names)
    for group, names in (("inputs and parameters", list(inputs) + list(parameters)),
                         ("outputs", list(outputs))):
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise FmiError(f"{twice[0]!r} is given twice among the {group}; an FMU names each "
                           f"variable once")
    both = sorted(set(outputs) & (set(inputs) | set(parameters)))
    if both:
        raise FmiError(f"{both[0]!r} is given as an output and as an input or parameter; an "
                       f"FMU names each variable once")
    system = circuit.compile()
    from .cli import check_names
    check_names(system, outputs, what="output")
    try:
        text = dumps(circuit, "toml")
        loads(text)
    except ModelFileError as exc:
        raise FmiError(f"{circuit.name}: the circuit cannot travel as a model file: {exc}") \
            from None
    cls = "".join(w.capitalize() for w in re.split(r"\W+", circuit.name) if w) or "Circuit"
    if not cls[0].isalpha():
        cls = "Circuit" + cls
    units = _units(circuit, system, list(inputs) + list(parameters), outputs)
    spec = {"inputs": list(inputs), "outputs": list(outputs), "parameters": list(parameters),
            "rtol": float(rtol), "units": units,
            "unit_definitions": {u: _base_units(u) for u in sorted(set(units.values()))}}
    if not (math.isfinite(rtol) and rtol > 0):
        raise FmiError(f"rtol must be a positive number, got {rtol!r}")
    folder = tempfile.mkdtemp(prefix="pvgraph-fmu-")
    try:
        script = os.path.join(folder, f"{cls}.py")
        with open(script, "w") as f:
            f.write(_SLAVE.format(cls=cls, model=MODEL_FILE, spec=SPEC_FILE,
                                  description=description or f"pvgraph circuit {circuit.name}"))
        model = os.path.join(folder, MODEL_FILE)
        with open(model, "w") as f:
            f.write(text)
        spec_path = os.path.join(folder, SPEC_FILE)
        with open(spec_path, "w") as f:
            json.dump(spec, f, indent=1)
        dest = os.path.abspath(path)
        os.makedirs(os.path.dirname(dest), exist_ok=True)
        built = FmuBuilder.build_FMU(script, dest=dest, project_files=[model, spec_path])
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return os.fspath(built)


def _units(circuit, system, params, outputs) -> dict:
    """The SI unit of each FMU variable that has one (``Pa``, ``m^3/s``; dimensionless and
    unknown ones left out): a parameter's from its field, an output's from the system."""
    from .units import parse_unit
    from .component import _UNIT
    out = {}
    known = circuit.parameters()
    for name in params:
        info = system.parameters.get(name)
        unit = getattr(info, "unit", None)
        if unit is None:
            m = _UNIT.search(known[name][1] or "")
            unit = m.group(1) if m else None
        out[name] = unit
    for name in outputs:
        try:
            out[name] = system.unit(name)
        except PvgraphError:
            out[name] = None
    kept = {}
    for name, unit in out.items():
        if not unit or unit.strip() in ("-", "1"):
            continue
        try:
            parse_unit(unit)
        except PvgraphError:
            continue
        kept[name] = unit
    return kept


def _base_units(unit: str) -> dict:
    """The exponents of the SI base units (and ``rad``) of ``unit``, as FMI 2.0's BaseUnit
    attributes, with its factor where it is not 1."""
    from .units import angle_power, parse_unit
    factor, dims = parse_unit(unit)
    out = {k: e for k, e in zip(("m", "kg", "s", "A", "K"), dims) if e}
    rad = angle_power(unit)
    if rad:
        out["rad"] = rad
    if factor != 1.0:
        out["factor"] = repr(float(factor))
    return out
