"""Body-model specifications: a kinematic tree, its parameter layout and its truncated cones, as data.

A *spec* (a JSON file, format ``swarmpose-body`` version 1, documented in ``docs/body-models.md``)
says how a body is built; a *subject* (:class:`Subject`) says how big one person is. A
:class:`~swarmpose.body.model.BodyModel` is a spec plus a subject.

Conventions (also in ``docs/notation.md``):

* Every frame of the tree is right-handed with, in the zero pose, ``x`` forward, ``y`` to the
  subject's left and ``z`` up. In the zero pose the person stands upright, legs straight down and
  arms hanging at the sides.
* A joint's local rotation is the matrix product of elementary rotations in the order the spec
  lists them, ``R = R_a1(s1*q1) @ R_a2(s2*q2) @ ...`` (column vectors), where ``a`` is ``x``, ``y`` or
  ``z`` and the sign ``s`` is ``-1`` for axes written ``-x``, ``-y``, ``-z``. Signs let one angle mean
  the same anatomical motion on both sides (positive = flexion, abduction, internal rotation).
* ``parent_from_child = [R_parent_rest_offset | offset] @ [R_local | 0]``: a joint sits at ``offset``
  (mm, in its parent's frame) and rotates about its own origin.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError, DataError, FormatError
from swarmpose.io.files import read_json_object

__all__ = [
    "ParameterSpec",
    "CoupledLimit",
    "JointSpec",
    "ConeSpec",
    "BodySpec",
    "Subject",
    "load_spec",
    "builtin_specs",
    "AXES",
]

AXES = {"x": 0, "y": 1, "z": 2}
SPEC_FORMAT = "swarmpose-body"
SPEC_VERSION = 1


@dataclass(frozen=True)
class ParameterSpec:
    """One scalar pose parameter.

    ``kind`` is ``"rotation"`` (radians) or ``"translation"`` (mm). ``sigma`` is the per-frame
    standard deviation at 60 fps used by the motion model (thesis sec. 5.3.2, [FL12] l.861).
    ``lower``/``upper`` are hard limits (may be infinite); ``group`` names the body part for staged
    search (thesis Table 6.1; Sharifi et al. sec. 3.4).
    """

    name: str
    kind: str
    lower: float
    upper: float
    sigma: float
    group: str
    description: str = ""
    tags: tuple[str, ...] = ()  # further group names, e.g. "head_twist"


@dataclass(frozen=True)
class CoupledLimit:
    """A region the parameters' own limits leave open but no body reaches: a pose is outside the limits when every
    parameter of ``parameters`` is above its value in ``above`` (radians or mm). The spec's shoulders use it for the
    double-turned branch of their angles (abduction and flexion both past 90 deg: the upper arm down again, its twist
    beyond the rotation's limits)."""

    parameters: tuple[str, ...]
    above: tuple[float, ...]
    description: str = ""


@dataclass(frozen=True)
class JointSpec:
    """A frame of the kinematic tree.

    ``offset`` names a subject measurement: the joint's origin in the parent's frame (mm).
    ``rotation`` is a tuple of ``(axis, parameter)`` pairs in matrix-product order; ``axis`` is one of
    ``x y z -x -y -z``. ``translation`` lists the parameter names added to the origin (root only).
    """

    name: str
    parent: str | None
    offset: str | None
    rotation: tuple[tuple[str, str], ...] = ()
    translation: tuple[str, ...] = ()


@dataclass(frozen=True)
class ConeSpec:
    """A truncated cone with elliptical cross-section fixed to a joint frame (thesis sec. 5.1.2).

    The cone axis runs from ``start_frac * m`` to ``end_frac * m`` in the joint's frame, where ``m``
    is the subject measurement named by ``axis``. Its radii at the two ends and the scale of its
    cross-section along the frame's ``x`` and ``y`` axes come from the subject (``Subject.cones``).
    """

    name: str
    joint: str
    axis: str
    start_frac: float = 0.0
    end_frac: float = 1.0
    side: str = "center"  # "left", "right" or "center": colour in overlays, left/right limb sets


@dataclass(frozen=True)
class Subject:
    """One person's measurements: offsets (mm, 3-vectors in the parent frame) and cone sizes.

    ``cones`` maps a cone name to ``(radius_start, radius_end, scale_x, scale_y)`` in mm.
    """

    name: str
    offsets: dict[str, tuple[float, float, float]]
    cones: dict[str, tuple[float, float, float, float]]
    source: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "source": self.source,
            "offsets": {k: [float(x) for x in v] for k, v in self.offsets.items()},
            "cones": {k: [float(x) for x in v] for k, v in self.cones.items()},
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, path: object = None) -> Subject:
        if not isinstance(data, dict):
            raise FormatError(f"expected a JSON object with 'offsets' and 'cones', got {type(data).__name__}",
                              path=path)
        for key in ("offsets", "cones"):
            if key in data and not isinstance(data[key], dict):
                raise FormatError(f"expected an object of name: numbers, got {type(data[key]).__name__}",
                                  path=path, field=key)
        try:
            offsets = {str(k): _vec3(v, path, f"offsets.{k}") for k, v in data["offsets"].items()}
            cones = {str(k): _vec4(v, path, f"cones.{k}") for k, v in data["cones"].items()}
        except KeyError as exc:
            raise FormatError(f"missing field {exc.args[0]!r}", path=path) from None
        return cls(name=str(data.get("name", "subject")), offsets=offsets, cones=cones,
                   source=str(data.get("source", "")))

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> Subject:
        path = Path(path)
        try:
            data = read_json_object(path)  # not UTF-8, not JSON or not an object: a FormatError naming the file
        except FileNotFoundError:
            raise DataError(f"{path}: subject file not found") from None
        except OSError as exc:
            raise DataError(f"{path}: cannot read the subject file: {exc}") from exc
        return cls.from_dict(data, path=path)


@dataclass(frozen=True)
class BodySpec:
    """A complete body-model specification (see the module docstring)."""

    name: str
    description: str
    parameters: tuple[ParameterSpec, ...]
    joints: tuple[JointSpec, ...]
    cones: tuple[ConeSpec, ...]
    joints15: tuple[str, ...]
    default_subject: Subject
    variants: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    collision_pairs: tuple[tuple[str, str], ...] = ()
    coupled_limits: tuple[CoupledLimit, ...] = ()
    references: tuple[str, ...] = ()
    extra_markers: tuple[tuple[str, str, str], ...] = ()  # (marker name, joint, measurement)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, path: object = None) -> BodySpec:
        """Build and validate a spec from its JSON form; errors name the file and the field."""
        if data.get("format") != SPEC_FORMAT:
            raise FormatError(f"expected format {SPEC_FORMAT!r}, got {data.get('format')!r}",
                              path=path, field="format")
        if data.get("version") != SPEC_VERSION:
            raise FormatError(f"unsupported version {data.get('version')!r} (expected {SPEC_VERSION})",
                              path=path, field="version")
        for key in ("name", "parameters", "joints", "cones", "joints15", "default_subject"):
            if key not in data:
                raise FormatError("missing field", path=path, field=key)
        params = []
        scales: dict[str, float] = {}
        for i, p in enumerate(data["parameters"]):
            where = f"parameters[{i}]"
            try:
                kind = p["kind"]
                if kind not in ("rotation", "translation"):
                    raise FormatError(f"kind must be 'rotation' or 'translation', got {kind!r}",
                                      path=path, field=where + ".kind")
                scale = np.pi / 180.0 if (kind == "rotation" and p.get("unit", "deg") == "deg") else 1.0
                scales[str(p["name"])] = scale
                lower = -np.inf if p.get("lower") is None else float(p["lower"]) * scale
                upper = np.inf if p.get("upper") is None else float(p["upper"]) * scale
                params.append(ParameterSpec(
                    name=str(p["name"]), kind=kind, lower=lower, upper=upper,
                    sigma=float(p["sigma"]) * scale, group=str(p["group"]),
                    description=str(p.get("description", "")),
                    tags=tuple(str(t) for t in p.get("tags", []))))
            except KeyError as exc:
                raise FormatError("missing field", path=path, field=f"{where}.{exc.args[0]}") from None
            if not lower < upper:
                raise FormatError(f"lower {lower} is not below upper {upper}", path=path, field=where)
            if not params[-1].sigma > 0:
                raise FormatError("sigma must be positive", path=path, field=where + ".sigma")
        joints = []
        for i, j in enumerate(data["joints"]):
            where = f"joints[{i}]"
            try:
                rotation = tuple((str(ax), str(pn)) for ax, pn in j.get("rotation", []))
                joints.append(JointSpec(name=str(j["name"]), parent=j["parent"], offset=j.get("offset"),
                                        rotation=rotation, translation=tuple(j.get("translation", []))))
            except (KeyError, ValueError, TypeError) as exc:
                raise FormatError(f"bad joint entry ({exc})", path=path, field=where) from None
        cones = []
        for i, c in enumerate(data["cones"]):
            try:
                cones.append(ConeSpec(name=str(c["name"]), joint=str(c["joint"]), axis=str(c["axis"]),
                                      start_frac=float(c.get("start_frac", 0.0)),
                                      end_frac=float(c.get("end_frac", 1.0)),
                                      side=str(c.get("side", "center"))))
            except KeyError as exc:
                raise FormatError("missing field", path=path, field=f"cones[{i}].{exc.args[0]}") from None
        spec = cls(
            name=str(data["name"]),
            description=str(data.get("description", "")),
            parameters=tuple(params),
            joints=tuple(joints),
            cones=tuple(cones),
            joints15=tuple(data["joints15"]),
            default_subject=Subject.from_dict(data["default_subject"], path=path),
            variants={str(k): v for k, v in data.get("variants", {}).items()},
            collision_pairs=tuple(tuple(p) for p in data.get("collision_pairs", [])),
            coupled_limits=_coupled_limits(data.get("coupled_limits", []), scales, path),
            references=tuple(data.get("references", [])),
            extra_markers=tuple(tuple(m) for m in data.get("extra_markers", [])),
        )
        spec.validate(path=path)
        return spec

    def validate(self, *, path: object = None) -> None:
        """Check names and references: every parent, parameter, measurement and cone must exist."""
        pnames = self.param_names
        if len(set(pnames)) != len(pnames):
            raise FormatError("duplicate parameter names", path=path, field="parameters")
        seen: set[str] = set()
        used: list[str] = []
        for i, j in enumerate(self.joints):
            where = f"joints[{i}] ({j.name})"
            if j.name in seen:
                raise FormatError("duplicate joint name", path=path, field=where)
            if (j.parent is None) != (i == 0):
                raise FormatError("the first joint, and only it, is the root (parent null)",
                                  path=path, field=where)
            if j.parent is not None and j.parent not in seen:
                raise FormatError(f"parent {j.parent!r} must be listed before the joint", path=path,
                                  field=where)
            if j.offset is not None and j.offset not in self.default_subject.offsets:
                raise FormatError(f"offset {j.offset!r} is not a measurement of default_subject",
                                  path=path, field=where)
            for ax, pn in j.rotation:
                if ax.lstrip("-") not in AXES or ax.count("-") > 1:
                    raise FormatError(f"axis {ax!r} is not one of x y z -x -y -z", path=path, field=where)
                if pn not in pnames:
                    raise FormatError(f"unknown parameter {pn!r}", path=path, field=where)
                used.append(pn)
            for pn in j.translation:
                if pn not in pnames:
                    raise FormatError(f"unknown parameter {pn!r}", path=path, field=where)
                used.append(pn)
            seen.add(j.name)
        if sorted(used) != sorted(pnames):
            missing = set(pnames) - set(used)
            twice = {p for p in used if used.count(p) > 1}
            raise FormatError(f"every parameter must drive exactly one axis (unused: {sorted(missing)}, "
                              f"repeated: {sorted(twice)})", path=path, field="joints")
        if len(self.joints15) != 15 or any(n not in seen for n in self.joints15):
            raise FormatError("joints15 must list 15 joint names of the tree (HumanEva order)",
                              path=path, field="joints15")
        for c in self.cones:
            if c.joint not in seen:
                raise FormatError(f"cone {c.name!r}: unknown joint {c.joint!r}", path=path, field="cones")
            if c.axis not in self.default_subject.offsets:
                raise FormatError(f"cone {c.name!r}: unknown measurement {c.axis!r}", path=path,
                                  field="cones")
            if c.name not in self.default_subject.cones:
                raise FormatError(f"cone {c.name!r} has no size in default_subject", path=path,
                                  field="default_subject.cones")
        cone_names = {c.name for c in self.cones}
        for a, b in self.collision_pairs:
            if a not in cone_names or b not in cone_names:
                raise FormatError(f"collision pair ({a}, {b}) names an unknown cone", path=path,
                                  field="collision_pairs")
        bounds = {p.name: (p.lower, p.upper) for p in self.parameters}
        for i, c in enumerate(self.coupled_limits):
            for name, value in zip(c.parameters, c.above, strict=True):
                if name not in bounds:
                    raise FormatError(f"unknown parameter {name!r}", path=path, field=f"coupled_limits[{i}]")
                if not bounds[name][0] < value < bounds[name][1]:
                    raise FormatError(f"{name}: {value!r} is not inside the parameter's limits, so the region "
                                      "would be empty or the whole range", path=path, field=f"coupled_limits[{i}]")
        for vname, changes in self.variants.items():
            for cname in changes:
                if cname not in cone_names:
                    raise FormatError(f"variant {vname!r} changes unknown cone {cname!r}", path=path,
                                      field=f"variants.{vname}")


def _coupled_limits(entries: Any, scales: dict[str, float], path: object) -> tuple[CoupledLimit, ...]:
    """``coupled_limits`` of a spec's JSON: ``[{"parameters": [A, B, ...], "above": [a, b, ...]}]`` in the
    parameters' own units (degrees unless a rotation says ``"unit": "rad"``), converted like their limits."""
    if not isinstance(entries, list):
        raise FormatError("expected a list", path=path, field="coupled_limits")
    out = []
    for i, e in enumerate(entries):
        where = f"coupled_limits[{i}]"
        try:
            names = tuple(str(n) for n in e["parameters"])
            values = tuple(float(v) for v in e["above"])
        except KeyError as exc:
            raise FormatError("missing field", path=path, field=f"{where}.{exc.args[0]}") from None
        except (TypeError, ValueError):
            raise FormatError("parameters must be names and above numbers", path=path, field=where) from None
        if len(names) < 2 or len(names) != len(values) or not np.all(np.isfinite(values)):
            raise FormatError(f"expected two or more parameters and as many finite values above, got {len(names)} "
                              f"and {len(values)}", path=path, field=where)
        above = tuple(v * scales.get(n, 1.0) for n, v in zip(names, values, strict=True))
        out.append(CoupledLimit(parameters=names, above=above, description=str(e.get("description", ""))))
    return tuple(out)


def _vec3(v: Any, path: object, fld: str) -> tuple[float, float, float]:
    try:
        out = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        raise FormatError("expected 3 numbers", path=path, field=fld) from None
    if len(out) != 3 or not np.all(np.isfinite(out)):
        raise FormatError(f"expected 3 finite numbers, got {v!r}", path=path, field=fld)
    return out  # type: ignore[return-value]


def _vec4(v: Any, path: object, fld: str) -> tuple[float, float, float, float]:
    try:
        out = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        raise FormatError("expected 4 numbers", path=path, field=fld) from None
    if len(out) != 4 or not np.all(np.isfinite(out)) or min(out) <= 0:
        raise FormatError(f"expected 4 positive numbers (r_start, r_end, scale_x, scale_y), got {v!r}",
                          path=path, field=fld)
    return out  # type: ignore[return-value]


def builtin_specs() -> tuple[str, ...]:
    """Names of the body models shipped with swarmpose."""
    files = resources.files("swarmpose.models")
    return tuple(sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".json")))


def load_spec(name_or_path: str | Path) -> BodySpec:
    """Load a shipped spec by name (``"balan31"``, ``"full45"``) or a spec file by path."""
    path: object
    if isinstance(name_or_path, str) and name_or_path in builtin_specs():
        res = resources.files("swarmpose.models") / f"{name_or_path}.json"
        path = f"swarmpose/models/{name_or_path}.json"
        data = json.loads(res.read_text(encoding="utf-8"))  # shipped with the package
    else:
        path = Path(name_or_path)
        if not path.is_file():
            raise ConfigError(f"unknown body model {str(name_or_path)!r}: not a shipped model "
                              f"({', '.join(builtin_specs())}) and not a file")
        try:
            data = read_json_object(path)  # not UTF-8, not JSON or not an object: a FormatError naming the file
        except OSError as exc:
            raise DataError(f"{path}: cannot read the body model spec: {exc}") from exc
    return BodySpec.from_dict(data, path=path)
