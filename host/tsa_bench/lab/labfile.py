"""A lab file: the rigs that run at once, read and checked whole before anything moves.

Format (YAML)::

    name: four-sim-rigs                  # required; runs are tagged with it (metadata "lab")
    description: ...
    defaults: {protocol: lifetime, bench: sim}    # any rig key but name, for every rig
    rigs:                                # required, at least one
      - name: A                          # required, unique: letters, digits, . _ -
        port: /dev/ttyACM0               # a serial device, or sim:// (or absent): the bench's own backend
        bench: my-rig-A.yaml             # required (here or in defaults): the rig's bench file
        protocol: lifetime               # required (here or in defaults)
        variables: {load_g: 350}         # values for variables the protocol declares (run --set)
        seed: 1                          # simulated rigs only: noise seed
        speed: 10                        # simulated rigs only: real-time factor (absent: as fast as possible)
        meta: {sample: S3, operator: ana}   # stored in the run's metadata (run --meta)

A relative path is looked up beside the lab file first, then as ``tsa-bench run`` looks
it up (the current folder, then the shipped configs: ``lifetime``, ``sim``).

Contract: :func:`read_lab` returns a :class:`Lab` only when every rig checks out as
``tsa-bench run`` would check it (bench file, protocol with its variables compiled under
the bench's limits, every device command fitting the wire, port policy, a serial device
that exists, one rig per serial port, seed and speed only where a simulation runs); else
:class:`LabFileError` carries every problem at once, each ``FILE:LINE:COL: message``
(problems inside a bench or protocol file keep that file's own position).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from yaml import MappingNode, Node, ScalarNode, SequenceNode

from tsa_bench.userfiles import DocumentError, YamlDocument, read_yaml

TOP_KEYS = ("name", "description", "defaults", "rigs")
RIG_KEYS = ("name", "port", "bench", "protocol", "variables", "seed", "speed", "meta")
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
SIM_SCHEME = "sim://"


class LabFileError(ValueError):
    """Every problem of a lab file, one ``FILE:LINE:COL: message`` per line."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems
        super().__init__("\n".join(problems))


@dataclass(frozen=True)
class Rig:
    """One rig of a lab, checked: paths resolved, values typed."""

    name: str
    protocol: Path
    bench: Path
    port: str | None                    # a serial device or URL; None: the bench file's backend
    backend: str                        # what runs it: "sim", "simavr" or "serial"
    seed: int | None = None
    speed: float | None = None
    variables: dict[str, Any] = field(default_factory=dict)
    meta: dict[str, str] = field(default_factory=dict)
    plan_name: str = ""
    load_g: float | None = None         # the protocol's load with these variables (g)
    where: str = ""                     # "lab.yaml:12:5", for messages


@dataclass(frozen=True)
class Lab:
    name: str
    path: Path
    rigs: list[Rig]
    description: str = ""


def _find(text: str, lab_dir: Path, kind: str) -> Path:
    from tsa_bench.shipped import find_config

    beside = lab_dir / text
    if not Path(text).is_absolute() and beside.is_file():
        return beside.resolve()
    found, _ = find_config(text, kind)
    return found.resolve() if found.exists() else Path(text)


class _Checker:
    def __init__(self, doc: YamlDocument, allow_url: bool, trust_firmware_dir: bool) -> None:
        self.doc, self.allow_url, self.trust_firmware_dir = doc, allow_url, trust_firmware_dir
        self.problems: list[str] = []
        self.lab_dir = Path(doc.filename).resolve().parent
        self.values: dict[int, Any] = {}   # id(node) -> its plain value
        self._walk(doc.root, doc.data())

    def _walk(self, node: Node | None, value: Any) -> None:
        if node is None:
            return
        self.values[id(node)] = value
        if isinstance(node, MappingNode) and isinstance(value, dict):
            for k, v in node.value:
                if isinstance(k, ScalarNode) and k.value in value:
                    self._walk(v, value[k.value])
        elif isinstance(node, SequenceNode) and isinstance(value, list):
            for v, item in zip(node.value, value):
                self._walk(v, item)

    def add(self, node: Node | None, message: str, details: list[str] = ()) -> None:
        """A problem at ``node``; ``details`` (lines of another file's errors) follow it, indented."""
        self.problems.append(str(self.doc.error(node, message)))
        self.problems += [f"  {line}" for line in details]

    def mapping(self, node: Node, keys: tuple[str, ...], what: str) -> dict[str, Node]:
        if not isinstance(node, MappingNode):
            self.add(node, f"{what}: expected a mapping")
            return {}
        out: dict[str, Node] = {}
        for k, v in node.value:
            if not isinstance(k, ScalarNode) or k.value not in keys:
                self.add(k, f"{what}: unknown key {getattr(k, 'value', '?')!r} (allowed: {', '.join(keys)})")
            elif k.value in out:
                self.add(k, f"{what}: {k.value} given twice")
            else:
                out[k.value] = v
        return out

    def scalar(self, node: Node, what: str) -> Any:
        value = self.values.get(id(node))
        if isinstance(value, (dict, list)) or value is None:
            self.add(node, f"{what}: expected a single value")
            return None
        return value

    def pairs(self, node: Node, what: str) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if not isinstance(node, MappingNode):
            self.add(node, f"{what}: expected a mapping of name: value")
            return out
        for k, v in node.value:
            value = self.scalar(v, f"{what}.{getattr(k, 'value', '?')}")
            if value is not None:
                out[str(k.value)] = value
        return out

    def rig(self, node: Node, defaults: dict[str, Node], index: int) -> Rig | None:
        keys = {**defaults, **self.mapping(node, RIG_KEYS, f"rigs[{index}]")}
        n0 = len(self.problems)
        name = self.scalar(keys["name"], "name") if "name" in keys else None
        if "name" not in keys:
            self.add(node, f"rigs[{index}]: every rig needs a name")
        elif name is not None and not NAME.match(str(name)):
            self.add(keys["name"], f"rig name {name!r}: use letters, digits, '.', '_' or '-' (at most 64)")
        label = f"rig {name}" if name is not None else f"rigs[{index}]"
        for key in ("protocol", "bench"):
            if key not in keys:
                self.add(node, f"{label}: no {key} (give it here or in defaults)")
        port = self.scalar(keys["port"], f"{label}: port") if "port" in keys else None
        seed = self.scalar(keys["seed"], f"{label}: seed") if "seed" in keys else None
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
            self.add(keys["seed"], f"{label}: seed must be a whole number >= 0")
        speed = self.scalar(keys["speed"], f"{label}: speed") if "speed" in keys else None
        if speed is not None and (isinstance(speed, bool) or not isinstance(speed, (int, float)) or not speed > 0
                                  or speed == float("inf")):
            self.add(keys["speed"], f"{label}: speed must be a real-time factor > 0")
        variables = self.pairs(keys["variables"], f"{label}: variables") if "variables" in keys else {}
        meta = {k: str(v) for k, v in (self.pairs(keys["meta"], f"{label}: meta") if "meta" in keys else {}).items()}
        for k, text in meta.items():
            if any(ch in text for ch in "\x00\r\n"):
                self.add(keys["meta"], f"{label}: meta.{k} holds a control character")
        if len(self.problems) > n0 or "protocol" not in keys or "bench" not in keys:
            return None
        return self.compiled(str(name), keys, port, seed, speed, variables, meta, label)

    def compiled(self, name: str, keys: dict[str, Node], port: Any, seed: Any, speed: Any,
                 variables: dict[str, Any], meta: dict[str, str], label: str) -> Rig | None:
        from tsa_bench.bench import BenchConfigError, load_bench
        from tsa_bench.bench.ports import PortPolicyError, check_port
        from tsa_bench.plan import PlanErrors, load_plan
        from tsa_bench.runner.commands import plan_problems
        from tsa_bench.runner.tracking import bench_problems

        n0 = len(self.problems)
        if port is not None:
            port = str(port)
            try:
                check_port(port, allow_url=self.allow_url)
            except PortPolicyError as exc:
                self.add(keys["port"], f"{label}: {exc}")
                return None
        sim_port = port is not None and port.lower().startswith(SIM_SCHEME)
        bench_file = _find(str(self.scalar(keys["bench"], "bench")), self.lab_dir, "bench")
        protocol_file = _find(str(self.scalar(keys["protocol"], "protocol")), self.lab_dir, "protocols")
        try:
            bench = load_bench(bench_file, allow_url=self.allow_url, trust_firmware_dir=self.trust_firmware_dir)
        except BenchConfigError as exc:
            self.add(keys["bench"], f"{label}: the bench file is not usable:", str(exc).splitlines())
            return None
        backend = "serial" if port is not None and not sim_port else bench.backend
        if sim_port and bench.backend != "sim":
            self.add(keys["port"], f"{label}: sim:// runs the simulated bench, but {bench_file} is a "
                                   f"{bench.backend} bench file")
        if backend == "serial" and port is None and not bench.port:
            self.add(keys["bench"], f"{label}: {bench_file} is a serial bench file without a port: give port")
        serial_port = port if port is not None and not sim_port else (bench.port if backend == "serial" else None)
        if serial_port and "://" not in serial_port and not Path(serial_port).exists():
            self.add(keys.get("port", keys["bench"]), f"{label}: no serial device {serial_port} (tsa-bench ports "
                                                      "lists the connected boards)")
        for key, value in (("seed", seed), ("speed", speed)):
            if value is not None and backend == "serial":
                self.add(keys[key], f"{label}: {key} applies only to a simulated rig (sim://, a sim or simavr "
                                    f"bench file); {serial_port} runs in real time")
        try:
            plan = load_plan(protocol_file, bench.limits, variables)
        except PlanErrors as exc:
            self.add(keys["protocol"], f"{label}: the protocol is not valid on bench '{bench.name}':",
                     str(exc).splitlines())
            return None
        problems = plan_problems(plan, bench.steps_per_turn) + bench_problems(plan, bench.name)
        if problems:
            self.add(keys["protocol"], f"{label}: {protocol_file} cannot be sent to bench '{bench.name}':", problems)
        if len(self.problems) > n0:
            return None
        return Rig(name=name, protocol=protocol_file, bench=bench_file,
                   port=None if sim_port else port, backend=backend, seed=seed,
                   speed=None if speed is None else float(speed), variables=variables, meta=meta,
                   plan_name=plan.name, load_g=plan.load_g, where=self.doc.where())


def read_lab(path: str | Path, *, allow_url: bool = False, trust_firmware_dir: bool = False) -> Lab:
    """The checked lab file (module contract); LabFileError with every problem otherwise."""
    try:
        doc = read_yaml(path, what="lab file")
        if doc.root is None:
            raise LabFileError([f"{path}: the lab file is empty (it needs name and rigs)"])
        c = _Checker(doc, allow_url, trust_firmware_dir)
    except DocumentError as exc:
        raise LabFileError([str(exc)]) from None
    top = c.mapping(doc.root, TOP_KEYS, "lab")
    name = c.scalar(top["name"], "name") if "name" in top else None
    if "name" not in top:
        c.add(doc.root, "lab: no name")
    elif name is not None and not NAME.match(str(name)):
        c.add(top["name"], f"lab name {name!r}: use letters, digits, '.', '_' or '-'")
    defaults = c.mapping(top["defaults"], tuple(k for k in RIG_KEYS if k != "name"), "defaults") \
        if "defaults" in top else {}
    rig_nodes = top.get("rigs")
    if rig_nodes is None:
        c.add(doc.root, "lab: no rigs")
    elif not isinstance(rig_nodes, SequenceNode) or not rig_nodes.value:
        c.add(rig_nodes, "rigs: expected a list of at least one rig")
    rigs: list[Rig] = []
    seen: dict[str, Node] = {}
    ports: dict[str, str] = {}
    for i, node in enumerate(rig_nodes.value if isinstance(rig_nodes, SequenceNode) else []):
        rig = c.rig(node, defaults, i)
        if rig is None:
            continue
        rig = Rig(**{**rig.__dict__, "where": str(doc.error(node, "").where)})
        if rig.name in seen:
            c.add(node, f"rig {rig.name}: the name is already used at line {seen[rig.name].start_mark.line + 1}")
        seen.setdefault(rig.name, node)
        if rig.port is not None:
            key = str(Path(rig.port).resolve()) if "://" not in rig.port else rig.port
            if key in ports:
                c.add(node, f"rig {rig.name}: port {rig.port} is already rig {ports[key]}'s")
            ports.setdefault(key, rig.name)
        rigs.append(rig)
    description = c.scalar(top["description"], "description") if "description" in top else ""
    if c.problems:
        raise LabFileError(c.problems)
    return Lab(name=str(name), path=Path(path).resolve(), rigs=rigs, description=str(description or ""))
