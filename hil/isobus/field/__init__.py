"""The field side of a Task Controller: prescription maps, path, section control (TC-GEO, TC-SC).

Everything runs in a local east/north plane in metres (:mod:`.geodesy`); files are GeoJSON in
WGS84 longitude/latitude (RFC 7946).

================  ==========================================================================
``geodesy``       WGS84 <-> local tangent plane (:class:`LocalFrame`)
``prescription``  rate zones from GeoJSON, rate at a point (:func:`load_prescription`)
``path``          the field, its work area and the legs driven, sampled in time
                  (:func:`load_field`, :func:`rectangular_field`)
``boom``          sections' widths and offsets (:class:`Boom`)
``coverage``      coverage and the section on/off rule (:class:`SectionControl`)
``as_applied``    what was applied, and the as-applied map (:class:`AsAppliedRecord`)
``task``          what a TC asks each period: set-points and section states (:class:`FieldTask`)
``drive``         the reference run: a path driven with an ideal implement (:func:`drive_field`)
``taskdata``      ISO 11783-10 TASKDATA grids (types 1, 2) as maps (:func:`load_taskdata_grid`)
================  ==========================================================================
"""

from hil.isobus.field.as_applied import AsAppliedArrays, AsAppliedRecord
from hil.isobus.field.boom import Boom, Section
from hil.isobus.field.coverage import Coverage, SectionControl, dead_reckoning, needed_ground
from hil.isobus.field.drive import ImplementModel, drive_field
from hil.isobus.field.geodesy import LocalFrame
from hil.isobus.field.path import (
    Field,
    FieldPath,
    Leg,
    Pose,
    field_from_geojson,
    field_to_geojson,
    load_field,
    rectangular_field,
)
from hil.isobus.field.prescription import (
    PrescriptionMap,
    Zone,
    load_prescription,
    prescription_from_geojson,
)
from hil.isobus.field.task import Command, FieldTask
from hil.isobus.field.taskdata import load_taskdata_grid

__all__ = [
    "AsAppliedArrays",
    "AsAppliedRecord",
    "Boom",
    "Command",
    "Coverage",
    "Field",
    "FieldPath",
    "FieldTask",
    "ImplementModel",
    "Leg",
    "LocalFrame",
    "Pose",
    "PrescriptionMap",
    "Section",
    "SectionControl",
    "Zone",
    "dead_reckoning",
    "drive_field",
    "field_from_geojson",
    "field_to_geojson",
    "load_field",
    "load_prescription",
    "load_taskdata_grid",
    "needed_ground",
    "prescription_from_geojson",
    "rectangular_field",
]
