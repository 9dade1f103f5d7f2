"""FMI-LS-REF reference experiments inside our FMUs (greyfmu.lsref) and ``cosim verify`` (cosim.regression.lsref)."""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import read_model_description

from cosim.cli import main
from cosim.regression.lsref import read_experiments
from cosim.record.results import read

FOLDER = "extra/org.fmi-standard.fmi-ls-ref/"
NS = "{http://fmi-standard.org/fmi-ls-manifest}"


def edited(fmu: Path, target: Path, edits: dict) -> Path:
    """A copy of ``fmu`` with members replaced or added (bytes), edited (a function of the old bytes) or
    removed (None); a member to edit or remove must be there."""
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as dst:
        missing = {name for name, data in edits.items() if not isinstance(data, bytes)} - set(src.namelist())
        assert not missing, sorted(missing)
        for info in src.infolist():
            edit = edits.get(info.filename, lambda data: data)
            data = edit(src.read(info)) if callable(edit) else edit
            if data is not None:
                dst.writestr(info, data)
        for name, data in edits.items():
            if name not in src.namelist() and isinstance(data, bytes):
                dst.writestr(name, data)
    return target


def test_every_fmu_carries_its_default_experiment_and_the_result_to_expect(built_fmus):
    """FMI-LS-REF 1.0.0-beta.1 layout: the manifest in extra/org.fmi-standard.fmi-ls-ref lists the
    experiments file (MA-HS-Experiments) and the result; the experiment is the DefaultExperiment;
    the result holds every output at each of its communication points; inputs only where the FMU has some."""
    for name, fmu in built_fmus.items():
        md = read_model_description(str(fmu))
        with zipfile.ZipFile(fmu) as archive:
            manifest = ElementTree.fromstring(archive.read(FOLDER + "fmi-ls-manifest.xml"))
            names = set(archive.namelist())
        assert manifest.tag == "fmiReferences" and manifest.get(NS + "fmi-ls-name") == "org.fmi-standard.fmi-ls-ref"
        assert manifest.get(NS + "fmi-ls-version") == "1.0.0-beta.1"
        roles = {r.get("source"): (r.get("role"), r.get("type")) for r in manifest.iter("Related")}
        assert roles["reference.exp"] == ("experiment/validation", "application/x-ma-hs-experiments"), name
        experiment, = read_experiments(fmu)
        de = md.defaultExperiment
        assert (experiment.start, experiment.stop, experiment.step) == \
            (float(de.startTime), float(de.stopTime), float(de.stepSize)), name
        outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        inputs = [v.name for v in md.modelVariables if v.causality == "input"]
        assert set(experiment.tolerances) == set(outputs), name
        with zipfile.ZipFile(fmu) as archive:
            header = archive.read(experiment.references).decode().splitlines()
        assert header[0] == ",".join(f'"{n}"' for n in ["time", *outputs]), name
        assert len(header) - 1 == round((experiment.stop - experiment.start) / experiment.step) + 1, name
        assert (experiment.stimuli is not None) == bool(inputs) == (FOLDER + "default_in.csv" in names), name
        assert "documentation/fmi-ls-ref.txt" in names


@pytest.mark.parametrize("name", ["PID", "Step", "BoilerTurbine"])
def test_cosim_verify_runs_the_experiment_and_matches_the_reference_bit_for_bit(built_fmus, name, capsys):
    """cosim runs the experiment on the DefaultExperiment's grid with the stimuli, as FMPy did when the
    FMU was built: the same numbers (and within the annotation's tolerances: exit 0)."""
    assert main(["verify", str(built_fmus[name])]) == 0
    out = capsys.readouterr().out
    assert f"{name}.fmu: 1 of 1 reference experiment(s) passed" in out
    assert "max |run − reference|" not in out                   # only failing signals are listed


def test_an_fmi3_fmu_carries_one_too_and_passes(capsys):
    from greyfmu.build import build_fmus

    fmu, = build_fmus(["PID3"])
    experiment, = read_experiments(fmu)
    assert experiment.stimuli and set(experiment.tolerances) == {"u", "e"}
    assert main(["verify", str(fmu)]) == 0
    assert "PID3.fmu: 1 of 1 reference experiment(s) passed" in capsys.readouterr().out


def test_an_altered_fmu_fails_verify_with_the_difference_report(built_fmus, tmp_path, capsys):
    """PID.fmu with its gain's default changed in the slave (the model description, GUID and references
    untouched): cosim verify exits 1, names u, and writes the report (HTML and PNG), by default in the
    current folder, run as a user runs it, in a process of its own."""
    with zipfile.ZipFile(built_fmus["PID"]) as archive:       # resources/_greyfmu_PID_<hash>/PID.py (issue 39)
        slave, = (n for n in archive.namelist() if n.startswith("resources/_greyfmu_PID_") and n.endswith("/PID.py"))
    altered = edited(built_fmus["PID"], tmp_path / "PID.fmu", {
        slave: lambda src: src.replace(b'self.parameter("Kc", 8.0345,', b'self.parameter("Kc", 8.5,')})
    done = subprocess.run([sys.executable, "-m", "cosim.cli", "verify", str(altered)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stderr
    out = done.stdout
    assert "experiment default (extra/org.fmi-standard.fmi-ls-ref/reference.exp): FAILED, 1 of 2 signals" in out
    assert "  u: FAILED (rtol 1e-06, atol" in out and "first at t = 10.1 s" in out          # t = 10 s: in the one-step time tolerance
    page = tmp_path / "PID.verify.html"
    assert f"difference report: {page.name}" in out and "u: FAILED" in page.read_text()
    assert page.with_suffix(".png").stat().st_size > 10_000


def test_an_fmu_without_reference_experiments_gets_a_clear_message(built_fmus, tmp_path, capsys):
    bare = edited(built_fmus["Gain"], tmp_path / "Gain.fmu", {n: None for n in (
        FOLDER + "fmi-ls-manifest.xml", FOLDER + "reference.exp", FOLDER + "default_in.csv", FOLDER + "default_ref.csv")})
    assert main(["verify", str(bare)]) == 2
    err = capsys.readouterr().err
    assert f"cosim: error: {bare}: the FMU carries no FMI-LS-REF reference experiments (no " \
           "extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml); nothing to verify" in err


def test_sources_outside_the_fmu_are_refused(built_fmus, tmp_path, capsys):
    for uri in ("../../../etc/passwd", "file:///etc/passwd", "/etc/passwd", "https://example.org/r.exp"):
        manifest = (f'<fmiReferences xmlns:fmi-ls="http://fmi-standard.org/fmi-ls-manifest"><Related '
                    f'type="application/x-ma-hs-experiments" source="{uri}" role="experiment"/></fmiReferences>')
        fmu = edited(built_fmus["Gain"], tmp_path / "Gain.fmu", {FOLDER + "fmi-ls-manifest.xml": manifest.encode()})
        assert main(["verify", str(fmu)]) == 2
        assert f"'{uri}'" in capsys.readouterr().err


def test_without_our_tolerances_the_fmi_cross_check_rule_judges(built_fmus, tmp_path, capsys):
    """Another vendor's experiment file carries no org.greyfmu.comparison annotation: the cross-check
    rule compares; written as the format's document writes it (times as attributes of <Experiment>)."""
    plain = (b'<Experiments name="x"><Experiment name="plain" startTime="0" stopTime="100" stepSize="0.1">'
             b'<Stimuli source="default_in.csv"/><References source="default_ref.csv"/></Experiment></Experiments>')
    fmu = edited(built_fmus["PID"], tmp_path / "PID.fmu", {FOLDER + "reference.exp": plain})
    experiment, = read_experiments(fmu)
    assert (experiment.name, experiment.stop, experiment.tolerances) == ("plain", 100.0, {})
    assert main(["verify", str(fmu)]) == 0
    with zipfile.ZipFile(fmu) as archive:
        reference = archive.read(FOLDER + "default_ref.csv")
    (tmp_path / "ref.csv").write_bytes(reference)
    assert np.isfinite(read(tmp_path / "ref.csv")["u"]).all()


@pytest.mark.parametrize("kc, passes", [(8.0345, True), (8.5, False)])
def test_an_experiments_parameter_set_is_applied_by_variable_name(built_fmus, tmp_path, kc, passes):
    """<Parameters source="kc.ssv"/>: an SSV applied as a binding without prefix (FMI-LS-REF 'Role
    parameter'): the FMU's own gain passes, another one fails against the same references."""
    ssv = (f'<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
           f'version="1.0" name="kc"><ssv:Parameters><ssv:Parameter name="Kc"><ssv:Real value="{kc}"/>'
           '</ssv:Parameter></ssv:Parameters></ssv:ParameterSet>').encode()
    fmu = edited(built_fmus["PID"], tmp_path / "PID.fmu", {
        FOLDER + "kc.ssv": ssv,
        FOLDER + "reference.exp": lambda exp: exp.replace(b'<Stimuli', b'<Parameters source="kc.ssv"/>\n    <Stimuli')})
    assert read_experiments(fmu)[0].parameters == FOLDER + "kc.ssv"
    assert main(["verify", str(fmu), "--report", str(tmp_path / "r.html")]) == (0 if passes else 1)
