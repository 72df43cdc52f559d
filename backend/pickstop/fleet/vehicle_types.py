"""Per-vehicle-type action mapping: the action type and parameter names a vehicle expects for a
pick, with PickStop's values mapped onto them (a YAML or JSON file, ``pickstop.vehicles``).

PickStop's own pick is ``pick`` with ``stopIndex``, ``trayId``, ``partId``, ``graspIndex``,
``jointNames`` and ``jointPositions`` (:data:`PICK_VALUES`). A type names the vehicles it
applies to (manufacturer, the factsheet's ``seriesName``, serial numbers: every one given must
match) and its pick: ``action_type``, ``parameters`` (vehicle key -> PickStop value; values not
named are not sent) and ``constants`` (vehicle key -> a fixed value)::

    format: pickstop.vehicles
    version: 1
    vehicle_types:
      - name: mm1
        manufacturer: acme
        series_name: MM-1
        pick:
          action_type: pickPart
          parameters: {station: trayId, load: partId}
          constants: {stationType: TRAY}
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from pickstop.errors import InputError

FORMAT = "pickstop.vehicles"
PICK = "pick"
PickValue = Literal["stopIndex", "trayId", "partId", "graspIndex", "jointNames", "jointPositions"]
PICK_VALUES: tuple[PickValue, ...] = (
    "stopIndex",
    "trayId",
    "partId",
    "graspIndex",
    "jointNames",
    "jointPositions",
)
Name = Annotated[str, Field(min_length=1, max_length=100)]
Constant = str | int | float | bool


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PickAction(_Strict):
    """How one vehicle type is asked to pick a part."""

    action_type: Name = PICK
    parameters: dict[Name, PickValue] = Field(
        default_factory=lambda: {str(k): k for k in PICK_VALUES},
        description="vehicle parameter key -> the PickStop value it carries",
    )
    constants: dict[Name, Constant] = Field(
        default_factory=dict, description="vehicle parameter key -> a fixed value"
    )
    blocking_type: Literal["NONE", "SOFT", "HARD"] = "HARD"

    @model_validator(mode="after")
    def _disjoint(self) -> PickAction:
        both = sorted(set(self.parameters) & set(self.constants))
        if both:
            raise ValueError(f"keys both mapped and constant: {', '.join(both)}")
        return self

    def values(self, ours: dict[str, Any]) -> list[dict[str, Any]]:
        """The action's parameters (``{"key", "value"}``) from PickStop's values ``ours``."""
        mapped = [{"key": k, "value": ours[v]} for k, v in self.parameters.items()]
        return mapped + [{"key": k, "value": c} for k, c in self.constants.items()]

    def ours(self, params: dict[str, Any]) -> dict[str, Any]:
        """Inverse of :meth:`values`: PickStop's values from a received action's parameters."""
        return {v: params[k] for k, v in self.parameters.items() if k in params}


DEFAULT_PICK = PickAction()


class VehicleType(_Strict):
    name: Name
    manufacturer: Name | None = None
    series_name: Name | None = None
    serial_numbers: list[Name] | None = None
    pick: PickAction = DEFAULT_PICK

    def matches(self, manufacturer: str, serial: str, series: str | None) -> bool:
        """Every criterion given holds (a series criterion needs the factsheet's series)."""
        return (
            (self.manufacturer is None or self.manufacturer == manufacturer)
            and (self.serial_numbers is None or serial in self.serial_numbers)
            and (self.series_name is None or self.series_name == series)
        )


class VehicleTypes(_Strict):
    format: Literal["pickstop.vehicles"] = "pickstop.vehicles"
    version: Literal[1] = 1
    vehicle_types: list[VehicleType] = Field(default_factory=list, max_length=1000)

    @model_validator(mode="after")
    def _unique(self) -> VehicleTypes:
        names = [t.name for t in self.vehicle_types]
        if len(set(names)) != len(names):
            raise ValueError("vehicle type names must be unique")
        return self

    def select(
        self, manufacturer: str, serial: str, series: str | None = None, name: str | None = None
    ) -> VehicleType | None:
        """The type named ``name`` (InputError if none is), else the first that matches the
        vehicle, else None (PickStop's own pick)."""
        if name is not None:
            for t in self.vehicle_types:
                if t.name == name:
                    return t
            known = ", ".join(t.name for t in self.vehicle_types) or "none"
            raise InputError(
                f"vehicle_type: no vehicle type {name!r} (known: {known})", field="vehicle_type"
            )
        return next((t for t in self.vehicle_types if t.matches(manufacturer, serial, series)),
                    None)  # fmt: skip


def parse_vehicle_types(doc: Any, source: str = "vehicle types") -> VehicleTypes:
    try:
        return VehicleTypes.model_validate(doc)
    except ValidationError as e:
        err = e.errors()[0]
        loc = ".".join(str(p) for p in err["loc"]) or "(root)"
        raise InputError(f"{source}: {loc}: {err['msg']}", field=loc) from None


MAX_BYTES = 1_000_000


def load_vehicle_types(path: str | Path) -> VehicleTypes:
    """Read a vehicle types file (YAML or JSON)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"vehicle types {path}: no such file", field="vehicle_types")
    if p.stat().st_size > MAX_BYTES:
        raise InputError(f"vehicle types {path}: larger than {MAX_BYTES} bytes",
                         field="vehicle_types")  # fmt: skip
    try:
        doc = yaml.safe_load(p.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        raise InputError(f"vehicle types {path}: not YAML ({e})", field="vehicle_types") from None
    return parse_vehicle_types(doc, f"vehicle types {path}")
