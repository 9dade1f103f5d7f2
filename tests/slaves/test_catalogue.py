"""The FMU catalogue and the org.greyfmu annotation (issue 45): every FMU of fmus/ findable with its
ports, parameters, sample time and what to wire, from the slaves' declarations, the same facts as
the built FMU's modelDescription.xml and documentation/index.html; the Grey/Gray alias and "did
you mean" for names.  About 15 s (every slave declared once)."""
from __future__ import annotations

import html
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import pytest

from greyfmu.build import fmi3_fmu_names, fmu_names
from greyfmu.catalogue import declared_description, entries, entry, markdown
from greyfmu.cli import main
from greyfmu.wiring import WiringError, annotate

CATALOGUE = Path("docs/catalogue.md")
CONTROLLERS = {"PID", "GrayPredictivePI", "GainScheduledPID", "SOPDTPredictive", "DigitalPI", "OSMMGPC"}


@pytest.fixture(scope="module")
def catalogue():
    return entries()


def test_every_fmu_is_in_the_catalogue_controllers_first(catalogue):
    assert sorted(e.name for e in catalogue) == sorted(fmu_names())
    page = markdown(catalogue)   # each entry stands for its FMI 3.0 build too
    assert all(f"FMI 3.0: `{name}.fmu`" in page for name in fmi3_fmu_names())
    assert {e.name for e in catalogue if e.group == "Controllers"} == CONTROLLERS
    assert [e.group for e in catalogue][:len(CONTROLLERS)] == ["Controllers"] * len(CONTROLLERS)


def test_docs_catalogue_is_the_generated_one(catalogue):
    assert CATALOGUE.read_text() == markdown(catalogue), \
        "docs/catalogue.md is stale: run `greyfmu catalogue -o docs/catalogue.md`"


@pytest.mark.parametrize("name", ["PID", "GainScheduledPID", "GM3t1Identifier", "Step", "PID3", "Step3"])
def test_one_source_the_built_fmu_says_what_the_catalogue_says(built_fmus, name):
    from greyfmu.build import build_fmus

    fmu = built_fmus[name] if name in built_fmus else build_fmus([name])[0]   # FMI 3.0: built on demand
    with zipfile.ZipFile(fmu) as archive:
        built = ElementTree.fromstring(archive.read("modelDescription.xml"))
        page = archive.read("documentation/index.html").decode()
    declared = entry(declared_description(name))
    assert entry(built) == declared
    assert html.escape(declared.wiring).replace("\n", "<br>") in page


def test_the_annotation_says_sample_time_and_what_to_wire(catalogue):
    gs = next(e for e in catalogue if e.name == "GainScheduledPID")
    assert gs.loop.sample_time == "Ts"
    assert {(p.name, p.role, p.when) for p in gs.loop.required_inputs()} == {
        ("r", "setpoint", ""), ("y", "measurement", ""), ("W", "scheduling", "law in 0 1 2 3"),
        ("Kp", "process", "law in 4"), ("T", "process", "law in 4"), ("tau", "process", "law in 4")}
    assert "Sampled every Ts (default 0.1 s)" in gs.wiring
    identifier = next(e for e in catalogue if e.name == "GM3t1Identifier")
    assert identifier.loop.sample_offset == "t_step"
    assert next(e for e in catalogue if e.name == "Sum").loop is None


def test_a_wiring_that_names_no_such_variable_is_refused():
    root = declared_description("PID")
    root.remove(root.find("VendorAnnotations"))
    for wiring, refusal in (({"ref": "setpoint"}, "wiring\\['ref'\\] names 'ref', which is not one of the FMU's inputs"),
                            ({"r": "setpoint if law"}, "condition 'law' is not"),
                            ({"r": "set-point"}, "role 'set-point' is none of")):
        with pytest.raises(WiringError, match=refusal):
            annotate(root, type("Slave", (), {"wiring": wiring}))


def test_names_grey_alias_and_did_you_mean(capsys):
    assert main(["info", "GreyPredictivePI"]) == 0
    assert capsys.readouterr().out.startswith("GrayPredictivePI (FMI 2.0 Co-Simulation; controllers)")
    assert main(["info", "GainSchedPID"]) == 2
    assert "unknown FMU GainSchedPID (did you mean GainScheduledPID" in capsys.readouterr().err
    assert main(["build", "GreyPredictivPI"]) == 2
    err = capsys.readouterr().err
    assert "did you mean GrayPredictivePI" in err and "valid names" not in err
