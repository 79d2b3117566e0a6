"""A study file written in US units (`units = "us"`): its tables read into file units once, at load
(crashlab.reconstruction.study), with each key's unit from the study schema (crashlab.reconstruction.schema) and
crashlab.file_units; docs/reference.md's US unit column."""
from __future__ import annotations

from pydantic import ValidationError

from crashlab.fields import study_path
from crashlab.file_units import field_unit, from_us, scaled, system_of
from crashlab.uncertainty import UncertainFile
from crashlab.units import us_factor

from .schema import Evidence, StudyFile


def in_file_units(data, path) -> dict:
    """A study file's table with every number in its file unit: as it is, or for a file that says
    units = "us" read from ft, mph, lb (crashlab.file_units: each key's unit is its description's, the US unit
    column of docs/reference.md). A [[free]] table's bounds take its field's unit, a counterfactual's set and
    shift values theirs (scale is a factor); hv_reference and near_optimal are lengths with the thesis
    objective only (the misfit's are sigmas)."""
    if system_of(data, path) != "us":
        return data
    raw = {k: v for k, v in data.items() if k not in ("free", "counterfactuals", "objective")}
    out = from_us(raw, StudyFile, {"uncertain": UncertainFile})
    if "free" in data:
        out["free"] = [_free_from_us(f) for f in data["free"]] if isinstance(data["free"], list) else data["free"]
    if "counterfactuals" in data:
        cfs = data["counterfactuals"]
        out["counterfactuals"] = [{k: ({p: scaled(v, us_factor(field_unit(p))) for p, v in t.items()}
                                       if k in ("set", "shift") and isinstance(t, dict) else t)
                                   for k, t in cf.items()} if isinstance(cf, dict) else cf for cf in cfs] \
            if isinstance(cfs, list) else cfs
    if "objective" in data:
        out["objective"] = _objective_from_us(data["objective"], out.get("evidence"))
    return out


def _free_from_us(entry):
    """A [[free]] table's lower and upper from its field's US unit (the field as crashlab.fields reads it)."""
    if not isinstance(entry, dict) or not isinstance(entry.get("field"), str):
        return entry  # the schema's check names what is wrong
    try:
        unit = field_unit(study_path(entry.get("vehicle"), entry["field"]))
    except (ValueError, KeyError, TypeError):
        return entry
    return {k: scaled(v, us_factor(unit)) if k in ("lower", "upper") else v for k, v in entry.items()}


def _objective_from_us(objective, evidence):
    """[objective] from US units: heading_weight ft/deg; hv_reference and near_optimal ft with the thesis
    objective (ObjectiveSection.mode, its default read from the evidence), sigmas with the misfit."""
    if not isinstance(objective, dict):
        return objective
    mode = objective.get("mode")
    if mode is None:
        try:
            mode = "misfit" if Evidence.model_validate(evidence or {}).has_uncertainty else "thesis"
        except ValidationError:
            mode = "misfit"  # the study's check names the evidence's problem
    lengths = ("hv_reference", "near_optimal") if mode == "thesis" else ()
    return {k: scaled(v, us_factor("m/deg")) if k == "heading_weight" else
            scaled(v, us_factor("m")) if k in lengths else v for k, v in objective.items()}
