"""``modelDescription.xml`` of the fertilizer plant FMU, for FMI 2.0 and FMI 3.0, from one
variable list (:mod:`plant_emulators.fmu_export.variables`)."""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

from plant_emulators.fmu_export.variables import Variable

MODEL_IDENTIFIER = "agrihil_fertilizer_plant"
TOKEN = "{a9c3e1d0-5f1e-4b6a-9a71-agrihilfert01}"
DESCRIPTION = ("agrihil's fertilizer-flow plant ([F]): servo motor and drive, four fluted-roller "
               "meters, fertilizer transport; the C core of the rig's native engine")


def _units(vs: list[Variable]) -> str:
    units = sorted({v.unit for v in vs if v.unit and v.unit != "1"})
    return "\n".join(f'    <Unit name={quoteattr(u)}/>' for u in units)


def _start(v: Variable) -> str:
    if v.start is None:
        return ""
    return f" start={quoteattr(repr(v.start) if v.kind == 'Real' else str(v.start))}"


def fmi3(vs: list[Variable], step_s: float, version: str) -> str:
    """The FMI 3.0 model description."""
    rows = []
    for vr, v in enumerate(vs):
        tag = "Float64" if v.kind == "Real" else "Int32"
        variability = ("continuous" if v.kind == "Real" and v.causality != "parameter"
                       else "fixed" if v.causality == "parameter" else "discrete")
        if v.causality == "input" and v.kind == "Real":
            variability = "continuous"
        unit = f" unit={quoteattr(v.unit)}" if v.unit and v.unit != "1" else ""
        initial = ' initial="exact"' if v.causality == "parameter" else ""
        rows.append(f'    <{tag} name={quoteattr(v.name)} valueReference="{vr}" '
                    f'causality="{v.causality}" variability="{variability}"{initial}{unit} '
                    f'description={quoteattr(v.description)}{_start(v)}/>')
    outputs = "\n".join(f'    <Output valueReference="{vr}"/>' for vr, v in enumerate(vs)
                        if v.causality == "output")
    outputs += "\n" + "\n".join(f'    <InitialUnknown valueReference="{vr}"/>'
                                 for vr, v in enumerate(vs) if v.causality == "output")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="agrihil fertilizer plant"
  description={quoteattr(DESCRIPTION)} generationTool="agrihil {version}"
  instantiationToken="{TOKEN}" variableNamingConvention="structured">
  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true"
    fixedInternalStepSize="{step_s!r}" canGetAndSetFMUState="false"
    canSerializeFMUState="false"/>
  <UnitDefinitions>
{_units(vs)}
  </UnitDefinitions>
  <DefaultExperiment startTime="0" stopTime="60" stepSize="{step_s!r}"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
{outputs}
  </ModelStructure>
</fmiModelDescription>
"""


def fmi2(vs: list[Variable], step_s: float, version: str) -> str:
    """The FMI 2.0 model description (value references from 1: 0 is FMI 2.0's time)."""
    rows = []
    index_of = {}
    for vr, v in enumerate(vs):
        if v.causality == "independent":
            continue                     # FMI 2.0 has no independent variable in the list
        index_of[vr] = len(rows) + 1
        variability = ("fixed" if v.causality == "parameter"
                       else "continuous" if v.kind == "Real" else "discrete")
        unit = f" unit={quoteattr(v.unit)}" if v.unit and v.unit != "1" else ""
        start = _start(v)
        initial = ' initial="exact"' if v.causality == "parameter" else ""
        tag = "Real" if v.kind == "Real" else "Integer"
        rows.append(f'    <ScalarVariable name={quoteattr(v.name)} valueReference="{vr}" '
                    f'causality="{v.causality}" variability="{variability}"{initial} '
                    f'description={quoteattr(v.description)}>\n'
                    f'      <{tag}{unit}{start}/>\n    </ScalarVariable>')
    outputs = "\n".join(f'      <Unknown index="{index_of[vr]}"/>' for vr, v in enumerate(vs)
                        if v.causality == "output")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="agrihil fertilizer plant"
  description={quoteattr(DESCRIPTION)} generationTool="agrihil {version}"
  guid="{TOKEN}" variableNamingConvention="structured" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true"
    canGetAndSetFMUstate="false" canSerializeFMUstate="false"/>
  <UnitDefinitions>
{_units(vs)}
  </UnitDefinitions>
  <DefaultExperiment startTime="0" stopTime="60" stepSize="{step_s!r}"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{outputs}
    </Outputs>
    <InitialUnknowns>
{outputs}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""
