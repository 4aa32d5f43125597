"""The check of the units convention (:mod:`dea_opt.units`) over what a run, a load path and a
sweep write: which names carry no unit, and which numbers of a JSON document are left without one.

It lives above the scenario layer because a sweep's columns include scenario keys (``load.scale``,
``law.H``), whose units the scenario's schema gives (:func:`dea_opt.scenario.docs.key_unit`).
"""

from __future__ import annotations

from ..units import UNITLESS, UNITLESS_OBJECTS, split_unit

__all__ = ["is_unitless", "unnamed_units"]


def is_unitless(name: str) -> bool:
    """Whether ``name`` is one of :data:`~dea_opt.units.UNITLESS`, or ends with ``_<one of them>`` (a region's
    ``medial_force_share``, a check's ``validity_strain``), or is a scenario key the schema gives
    no unit (a sweep's ``load.scale``, ``law.kind``)."""
    if name in UNITLESS or any(name.endswith(f"_{u}") for u in UNITLESS):
        return True
    return "." in name and _scenario_key_without_unit(name)


def _scenario_key_without_unit(name: str) -> bool:
    from ..scenario.docs import key_unit, schema_sections

    table, _, key = name.partition(".")
    known = any(t == table and any(key in m.model_fields for m in models) for t, models in schema_sections())
    return known and key_unit(name) == ""


def unnamed_units(data, where: str = "", stated: bool = False) -> list[str]:
    """Where a JSON document (or a dict) holds a number whose unit its name does not give: the
    paths (``regions.medial.peak``) of numbers (and lists of numbers) whose key has no unit
    suffix and is not one of :data:`~dea_opt.units.UNITLESS`, in no object that states its unit (a ``unit`` key,
    or its own key ending with one: ``peak_pressure_MPa: {medial: 2.1, lateral: 1.9}``) nor under
    one of :data:`~dea_opt.units.UNITLESS_OBJECTS`. Empty when every number is named by the convention."""
    found: list[str] = []
    if isinstance(data, dict):
        stated = stated or "unit" in data
        for key, value in data.items():
            path = f"{where}.{key}" if where else str(key)
            if key in UNITLESS_OBJECTS and isinstance(value, dict):
                continue
            named = split_unit(str(key))[1] is not None
            if _numbers(value):
                if not (stated or named or is_unitless(str(key))):
                    found.append(path)
            else:
                found += unnamed_units(value, path, stated or named)
    elif isinstance(data, list):
        for k, value in enumerate(data):
            found += unnamed_units(value, f"{where}[{k}]", stated)
    return found


def _numbers(value) -> bool:
    """A number, or a (nested) list holding numbers and nothing else but None."""
    if isinstance(value, bool):
        return False
    if isinstance(value, (int, float)):
        return True
    if isinstance(value, list) and value:
        return all(v is None or _numbers(v) for v in value) and any(v is not None for v in value)
    return False
