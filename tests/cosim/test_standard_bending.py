"""FMUs that bend the standard (issue 41, `cosim.read.conformance`): each rule of fmpy's model
description validation, broken in a copy of a C FMU's modelDescription.xml (tests/single_fmus.py:
Drive; binaries unchanged), is either tolerated (one ``cosim: warning:`` line naming the FMU, the
rule and the line, the run goes on and computes what the clean FMU computes; ``--strict``
refuses) or refused (exit 2 naming the rule and the line).  Before issue 41 every one of them was
refused ("Failed to validate modelDescription.xml")."""
from __future__ import annotations

import re

import fmpy
import numpy as np
import pytest

from cosim.cli import main
from cosim.read.conformance import RULES
from cosim.record.results import read
from single_fmus import build_drive
from testfmus import edited_copy


def _lines(text: str) -> str:
    """The description one variable per line (line 3 is the first ScalarVariable, u)."""
    return text.replace("<ModelVariables>", "<ModelVariables>\n").replace("</ScalarVariable>", "</ScalarVariable>\n")


#: variable -> its line in the description `_lines` writes
LINE = {name: 3 + i for i, name in enumerate(["u", "d", "k", "b", "x", "y", "yk", "yb", "yd", "gain"])}
UNITS = '<UnitDefinitions><Unit name="m"><BaseUnit m="1"/></Unit></UnitDefinitions>'

#: rule -> (edit of the description, the line the warning names, words the warning holds)
TOLERATED = {
    # Simulink's FMI Kit: a discrete variable left at FMI 2.0's default variability, continuous
    "variability": (lambda t: t.replace('name="k" valueReference="0" causality="input" variability="discrete"',
                                        'name="k" valueReference="0" causality="input"'),
                    LINE["k"], "variable 'k' is an Integer with variability=\"continuous\""),
    "unit-undefined": (lambda t: t.replace('<Real/></ScalarVariable>\n<ScalarVariable name="y"',
                                           '<Real unit="furlong"/></ScalarVariable>\n<ScalarVariable name="y"'),
                       LINE["x"], "variable 'x' has the unit 'furlong'"),
    "display-unit": (lambda t: t.replace("<DefaultExperiment", UNITS + "<DefaultExperiment").replace(
        '<Real/></ScalarVariable>\n<ScalarVariable name="yk"', '<Real unit="m" displayUnit="mm"/></ScalarVariable>\n'
        '<ScalarVariable name="yk"'), LINE["y"], "variable 'y' has the displayUnit 'mm'"),
    "calculated-start": (lambda t: t.replace('<Real/></ScalarVariable>\n<ScalarVariable name="yk"',
                                             '<Real start="4"/></ScalarVariable>\n<ScalarVariable name="yk"'),
                         LINE["y"], "variable 'y' has initial=\"calculated\" and start=\"4\""),
    "start-missing": (lambda t: t.replace('causality="input" variability="continuous"><Real start="0"/>',
                                          'causality="input" variability="continuous"><Real/>'),
                      LINE["u"], "variable 'u' (input, initial=\"exact\") has no start"),
    "combination": (lambda t: t.replace('causality="parameter" variability="fixed" initial="exact"',
                                        'causality="parameter" variability="fixed" initial="approx"'),
                    LINE["gain"], "variable 'gain' has causality=\"parameter\", variability=\"fixed\", "
                                  "initial=\"approx\""),
    "schema": (lambda t: t.replace('name="d" valueReference="1"', 'name="d" vendorFlag="1" valueReference="1"'),
               LINE["d"], "The attribute 'vendorFlag' is not allowed"),
}

#: rule -> (edit, the line the error names, words)
REFUSED = {
    "unique-names": (lambda t: t.replace('name="yd" valueReference="4"', 'name="yk" valueReference="4"'),
                     LINE["yk"], "variable 'yk' is declared 2 times"),
    "causality": (lambda t: t.replace('name="yd" valueReference="4" causality="output"',
                                      'name="yd" valueReference="4" initial="calculated" causality="result"'),
                  LINE["yd"], "variable 'yd' has causality=\"result\""),
}


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    return build_drive(tmp_path_factory.mktemp("drive"))


def _bent(drive, tmp_path, edit):
    fmu = edited_copy(drive, tmp_path / "Drive.fmu", lambda text: edit(_lines(text)))
    return fmu


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("cosim: warning:")]


def test_the_table_names_every_rule():
    assert set(TOLERATED) | set(REFUSED) | set(FMI3) == set(RULES)
    assert all(RULES[r].tolerated for r in TOLERATED) and not any(RULES[r].tolerated for r in REFUSED)


@pytest.mark.parametrize("rule", sorted(TOLERATED))
def test_a_tolerated_rule_warns_once_and_the_run_goes_on(rule, drive, tmp_path, capsys):
    """One warning naming the FMU, the rule and the line; the results are the clean FMU's, bit for
    bit; --strict refuses it (exit 2) with the same text."""
    edit, line, words = TOLERATED[rule]
    fmu = _bent(drive, tmp_path, edit)
    assert main(["run", str(fmu), "-o", str(tmp_path / "bent.csv"), "-q"]) == 0, capsys.readouterr().err
    warned = _warnings(capsys.readouterr().err)
    assert len(warned) == 1, warned
    assert f"Drive.fmu, modelDescription.xml line {line}: " in warned[0] and f"rule '{rule}'" in warned[0] \
        and words in warned[0] and "--strict refuses it" in warned[0], warned
    assert main(["run", str(drive), "-o", str(tmp_path / "clean.csv"), "-q"]) == 0
    assert not _warnings(capsys.readouterr().err)
    bent, clean = read(tmp_path / "bent.csv"), read(tmp_path / "clean.csv")
    assert bent.dtype.names == clean.dtype.names
    for name in clean.dtype.names:
        np.testing.assert_array_equal(bent[name], clean[name], err_msg=name)
    assert main(["run", str(fmu), "--strict", "-o", str(tmp_path / "strict.csv"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "cosim: error:" in err and f"rule '{rule}'" in err and "--strict" in err, err
    assert not (tmp_path / "strict.csv").exists()


@pytest.mark.parametrize("rule", sorted(REFUSED))
def test_a_refused_rule_names_the_rule_and_the_line(rule, drive, tmp_path, capsys):
    edit, line, words = REFUSED[rule]
    fmu = _bent(drive, tmp_path, edit)
    assert main(["validate", str(fmu)]) == 2
    err = capsys.readouterr().err
    assert f"Drive.fmu, modelDescription.xml line {line}: {words}" in err and f"rule '{rule}'" in err \
        and "cannot run" in err, err


def test_the_simulink_enumeration_runs_as_fmpy_without_validation_runs_it(drive, tmp_path, capsys):
    """The EMBRACE system's case (0002_ECS_SW.fmu: an Enumeration input left at variability
    continuous) on our C FMU: cosim's outputs are fmpy.simulate_fmu(validate=False)'s, which
    refuses the FMU with validate=True, as cosim did."""
    fmu = _bent(drive, tmp_path, TOLERATED["variability"][0])
    with pytest.raises(Exception, match="must have variability"):
        fmpy.simulate_fmu(str(fmu), output_interval=0.1)
    theirs = fmpy.simulate_fmu(str(fmu), validate=False, output_interval=0.1, start_values={"k": 3})
    assert main(["run", str(fmu), "--start-value", "k=3", "-o", str(tmp_path / "o.csv"), "-q"]) == 0
    ours = read(tmp_path / "o.csv")
    assert len(_warnings(capsys.readouterr().err)) == 1
    for name in ("x", "yk"):
        np.testing.assert_array_equal(ours[name].astype(float), theirs[name].astype(float), err_msg=name)


def test_what_cannot_run_is_still_refused(drive, tmp_path, capsys):
    """Broken XML and a declaredType that does not exist: fmpy cannot read them (refused, as
    before); the line is named."""
    broken = edited_copy(drive, tmp_path / "Broken.fmu", lambda t: t.replace("</ModelVariables>", ""))
    assert main(["validate", str(broken)]) == 2
    assert re.search(r"cannot read the model description of Broken\.fmu", capsys.readouterr().err)
    undeclared = edited_copy(drive, tmp_path / "Undeclared.fmu",
                             lambda t: t.replace('<Integer start="0"/>', '<Integer declaredType="Nope" start="0"/>'))
    assert main(["validate", str(undeclared)]) == 2
    assert "declaredType=\"Nope\" which has not been defined" in capsys.readouterr().err


#: FMI 3.0 rules on Types3 (tests/typefmus.py, one variable a line from line 8): rule -> (edit, line, words)
FMI3 = {
    "independent-count": (lambda t: t.replace('<Float64 name="time" valueReference="63" causality="independent" '
                                              'variability="continuous"/>', '<!-- no time -->'),
                          None, "0 independent variables (none)"),
    "independent-start": (lambda t: t.replace('causality="independent" variability="continuous"/>',
                                              'causality="independent" variability="continuous" start="0"/>'),
                          8, "variable 'time' is the independent variable and has start=\"0\""),
    "value-references": (lambda t: t.replace('<Float32 name="fecho" valueReference="20"',
                                             '<Float32 name="fecho" valueReference="0"').replace(
                             '<Output valueReference="20" dependencies="10"/>', ''),
                         19, "variable 'fecho' (Float32) has the value reference 0 of variable 'f' (Float32, line 9)"),
    "value-reference-types": (lambda t: t.replace('<UInt16 name="u16" valueReference="2"',
                                                  '<UInt16 name="u16" valueReference="1"').replace(
                                  '<Output valueReference="2" dependencies=""/>', ''),
                              11, "variable 'u16' (UInt16) has the value reference 1 of variable 'i8' (Int8, line 10)"),
}


@pytest.mark.parametrize("rule", sorted(FMI3))
def test_fmi3_rules(rule, tmp_path, capsys):
    from cfmus import build_c_fmu
    from typefmus import TYPES3, TYPES3_BODY

    edit, line, words = FMI3[rule]
    fmu = build_c_fmu(tmp_path, "Types3", edit(TYPES3), TYPES3_BODY, "3.0")
    at = f"Types3.fmu, modelDescription.xml{f' line {line}' if line else ''}: {words}"
    if RULES[rule].tolerated:
        assert main(["validate", str(fmu)]) == 0
        warned = _warnings(capsys.readouterr().err)
        assert len(warned) == 1 and at in warned[0] and f"rule '{rule}'" in warned[0], warned
        assert main(["validate", "--strict", str(fmu)]) == 2
    else:
        assert main(["validate", str(fmu)]) == 2
        err = capsys.readouterr().err
        assert at in err and "cannot run" in err, err
