"""What an importer reads in our FMUs (issue 13, item 6): mode parameters named by an IntEnum
(FMI 2.0: Integer with the items in the description; FMI 3.0 PID3: an Enumeration), a unit on
every physical variable with UnitDefinitions a tool can convert, and the generic blocks'
signals left to the units they are wired to."""

import shutil
from enum import IntEnum
import zipfile
from xml.etree import ElementTree

import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from cosim.read.description import describe
from cosim.errors import SetupError
from cosim.model.transforms import Affine
from cosim.model.units import BUILTIN, conversion, fmu_units, make_unit
from greyfmu.build import FMU_SOURCES, BuildError, _enumeration_items, build_fmus, fmu_names, slave_class

ALL = fmu_names()

MODES = {
    # FMU: mode parameter -> its IntEnum
    "PID": {"anti_windup": "AntiWindup", "derivative_on": "DerivativeOn", "form": "PIForm", "integral_mode": "IntegralMode"},
    "GainScheduledPID": {"law": "SchedulingLaw", "anti_windup": "AntiWindup", "derivative_on": "DerivativeOn",
                         "integral_mode": "IntegralMode"},
    "GrayPredictivePI": {"threshold": "Threshold", "anti_windup": "AntiWindup", "form": "PIForm",
                         "integral_mode": "IntegralMode"},
    "GreyPredictor": {"threshold": "Threshold"},
    "SOPDTPredictive": {"law": "ControlLaw"},
    "FourTank": {"time_varying": "FourTankModel"},
    "LookupTable": {"extrapolate": "Extrapolation"},
    "OSMMGPC": {"group": "ModelGroup", "efficiency": "EfficiencyForm", "adapt": "Adaptation", "method": "Estimator"},
    "TSEstimator": {"method": "Estimator", "dominance": "Dominance"},
}
COUNTS = {"seed", "identification_seed", "k_change", "ramp_origin", "delay", "N", "N1", "N2", "Nu", "n", "m",
          "n_points", "rules", "na", "p"}
"""Integer parameters that count or seed, not choose (they stay Integer)."""
GENERIC = {
    # generic blocks: their signals carry the units they are wired to
    "PID": ["r", "y", "u", "e", "u_min", "u_max", "u0"],
    "FOPDT": ["u", "d", "y", "K", "y0"],
    "FirstOrderFilter": ["u", "y"],
    "Gain": ["u", "y", "k"],
    "Sum": ["u1", "u2", "u3", "y"],
    "Step": ["y", "initial", "final"],
    "LookupTable": ["u", "y"],
}
PLANT_UNITS = {
    "BoilerTurbine": {"P": "kgf/cm2", "E": "MW", "L": "mm", "fuel": "%", "rate_fuel": "%/s"},
    "SteamHeader": {"y1": "MPa", "fuel": "kg/s", "v1": "%", "u1": "1"},
    "FourTank": {"u1": "1", "u2": "1", "h1": "1", "h4": "1"},
    "TSEstimator": {"h1": "1", "y_hat1": "1", "mae2": "1"},
    "OSMMGPC": {"r1": "MPa", "y2": "MPa", "u1": "1", "M_max": "1"},
}


NOT_BUILTIN = {"%/s": make_unit("%/s", factor=0.01, s=-1), "rad/s": make_unit("rad/s", rad=1, s=-1)}
"""Our units that cosim.model.units.BUILTIN does not define."""


def slave_choices(name):
    return slave_class(FMU_SOURCES / f"{name}.py")(instance_name="test").choices


@pytest.mark.parametrize("name", sorted(MODES))
def test_mode_parameters_are_integers_whose_description_and_range_give_the_intenums_members(built_fmus, name):
    """FMI 2.0 Integer, not Enumeration: libcosim 0.11.2 applies no ssv:Integer binding to an
    Enumeration variable (tests/peers/test_crosscheck.py, grey_fig312: grey_pi.u differs by 5.2)
    and aborts on an ssv:Enumeration one (ssp_parser.cpp:69 Internal error); its API refuses
    integer_initial_value on an Enumeration variable too, so there a libcosim user could not set them."""
    md = read_model_description(str(built_fmus[name]))
    choices = slave_choices(name)
    assert {parameter: enumeration.__name__ for parameter, enumeration in choices.items()} == MODES[name]
    variables = {v.name: v for v in md.modelVariables}
    for parameter, enumeration in choices.items():
        variable = variables[parameter]
        assert variable.type == "Integer"
        assert (int(variable.min), int(variable.max)) == (min(enumeration), max(enumeration))
        assert int(variable.start) in set(enumeration)
        assert variable.description.endswith(
            "(" + ", ".join(f"{member.value} = {member.name}" for member in enumeration) + ")"), variable.description


@pytest.mark.parametrize("name", ALL)
def test_the_integer_parameters_left_count_or_seed(built_fmus, name):
    """An int-coded choice added later without an IntEnum fails here."""
    md = read_model_description(str(built_fmus[name]))
    integers = {v.name for v in md.modelVariables if v.type == "Integer" and v.causality == "parameter"}
    assert integers - set(MODES.get(name, {})) <= COUNTS


def test_an_enumeration_value_that_is_no_item_is_refused_naming_the_items(built_fmus, tmp_path, capsys):
    md = read_model_description(str(built_fmus["PID"]))
    shutil.unpack_archive(built_fmus["PID"], tmp_path, "zip")
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=str(tmp_path), modelIdentifier="PID", instanceName="test")
    fmu.instantiate(loggingOn=True)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    refs = {v.name: v.valueReference for v in md.modelVariables}
    fmu.setInteger([refs["integral_mode"]], [2])  # an item, as fmi2Integer (an ssv:Integer binding)
    assert fmu.getInteger([refs["integral_mode"]]) == [2]
    fmu.setInteger([refs["integral_mode"]], [5])
    with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
        fmu.exitInitializationMode()
    assert "integral_mode = 5 is not an item of IntegralMode (1 = METHOD1, 2 = METHOD2, 3 = METHOD3)" \
        in capsys.readouterr().out
    # fmi2Fatal: no further call, not even fmi2FreeInstance (FMI 2.0 §2.1.3)


@pytest.mark.parametrize("name", ALL)
def test_every_real_variable_has_a_unit_or_is_documented_as_wired(built_fmus, name):
    md = read_model_description(str(built_fmus[name]))
    with zipfile.ZipFile(built_fmus[name]) as archive:
        page = archive.read("documentation/index.html").decode()
    for variable in md.modelVariables:
        if variable.type == "Real":
            unit = variable.unit or "as wired"
            assert f"<td>{variable.name}</td><td>{variable.causality}</td><td>{variable.variability}</td>" \
                   f"<td>Real</td><td>{unit}</td>" in page, variable.name
    for generic in GENERIC.get(name, []):
        assert next(v for v in md.modelVariables if v.name == generic).unit is None, generic


@pytest.mark.parametrize("name", sorted(PLANT_UNITS))
def test_plant_signals_carry_their_units(built_fmus, name):
    md = read_model_description(str(built_fmus[name]))
    units = {v.name: v.unit for v in md.modelVariables}
    assert {n: units[n] for n in PLANT_UNITS[name]} == PLANT_UNITS[name]


@pytest.mark.parametrize("name", ALL)
def test_unit_definitions_convert_as_the_masters_builtin_units(built_fmus, name):
    """Each UnitDefinitions/Unit of ours is the unit cosim knows by that name (NIST SP 811
    factors): kgf/cm2 = 98066.5 Pa, % = 0.01, MW = 1e6 W, mm = 1e-3 m; %/s and rad/s as written here."""
    md = read_model_description(str(built_fmus[name]))
    used = {v.unit for v in md.modelVariables if v.unit}
    defined = fmu_units(describe(built_fmus[name], where=name, file=name).unit_definitions, name)
    assert set(defined) == used
    for unit in defined.values():
        assert unit.same_as({**BUILTIN, **NOT_BUILTIN}[unit.name]), unit.describe()


def test_a_generic_signal_declared_dimensionless_would_be_refused_or_rescaled():
    """Why PID, FOPDT, Gain ... declare no unit: cosim (SSP 1.0 unit conversion) refuses a
    connection from a dimensionless "1" to a force in N (ssp/pid_mass_damper wires PID.u to a
    force input), and converts a % output into "1" by 0.01; without a unit it takes the value as is."""
    with pytest.raises(SetupError, match="the dimensions differ"):
        conversion(BUILTIN["1"], BUILTIN["N"])
    assert conversion(BUILTIN["%"], BUILTIN["1"]) == Affine(0.01, 0.0)


def test_the_fmi3_pid_declares_its_integral_mode_as_an_enumeration(tmp_path):
    """FMI 3.0 (PID3, the FMI 3.0 build of PID): ``<Enumeration declaredType>`` and a described ``EnumerationType``."""
    (fmu,) = build_fmus(["PID3"], out_dir=tmp_path)
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    mode = next(v for v in md.modelVariables if v.name == "integral_mode")
    assert (mode.type, mode.declaredType.name, int(mode.start)) == ("Enumeration", "IntegralMode", 3)
    with zipfile.ZipFile(fmu) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    items = {item.get("name"): item.get("description")
             for item in root.find("TypeDefinitions/EnumerationType[@name='IntegralMode']")}
    assert list(items) == ["METHOD1", "METHOD2", "METHOD3"] and items["METHOD2"].startswith("(2.11)")


def test_an_undocumented_enumeration_member_is_refused_by_the_build():
    class Mode(IntEnum):
        """Two modes."""

        A = 1
        """Documented."""
        B = 2

    with pytest.raises(BuildError, match=r"members \['B'\] of IntEnum Mode"):
        _enumeration_items("Test", Mode)
