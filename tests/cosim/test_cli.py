"""The ``cosim`` command on its own (cosim.cli): run, validate, info and pack on a small system
of real FMUs, exit codes and what each prints, without a scenario of ssp/."""
from __future__ import annotations

import zipfile

import pytest

from cosim.cli import main
from cosim.record.results import read
from ssdgen import ssd_text, write_system

COMPONENTS = {"step": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input", "y": "output"})}
CONNECTIONS = [("step", "y", "gain", "u")]


def _system(tmp_path, twin_fmus, **kw):
    text = ssd_text("pair", COMPONENTS, CONNECTIONS, parameters={"gain": {"k": 4.0}}, **kw)
    return write_system(tmp_path / "pair", {"Step.fmu": twin_fmus["Step"], "Gain.fmu": twin_fmus["Gain"]}, text)


def test_run_writes_results_and_metadata(tmp_path, twin_fmus, capsys):
    folder = _system(tmp_path, twin_fmus, stop=2.0, step=0.5)
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "cosim: pair: 2 FMUs, 1 connection, t = 0..2 s, step 0.5 s (annotation org.greyfmu.simulation)" in printed
    assert f"cosim: results: {out} (5 samples; metadata {out.with_suffix('.json')})" in printed
    result = read(out)
    assert list(result.dtype.names) == ["time", "step.y", "gain.u", "gain.y"] and result["gain.y"][-1] == 4.0


def test_validate_without_a_step_in_the_ssd_says_so(tmp_path, twin_fmus, capsys):
    """It checks a placeholder grid but reports what the SSD gives, not the placeholder (issue 21,
    item 4: it printed "step 1 s (command line)", a step nobody gave, while run refuses the file)."""
    folder = _system(tmp_path, twin_fmus, step=None)
    assert main(["validate", str(folder)]) == 0
    assert (f"cosim: {folder}: valid — 2 FMUs, 1 connection, 1 parameter value; stop 1 s; "
            "no step size in the SSD (run needs --step)" in capsys.readouterr().out)
    assert main(["run", str(folder), "-o", str(tmp_path / "o.csv"), "-q"]) == 2
    assert "no step size" in capsys.readouterr().err
    folder = _system(tmp_path, twin_fmus, step=0.25)
    assert main(["validate", str(folder)]) == 0
    assert "step 0.25 s (annotation org.greyfmu.simulation)" in capsys.readouterr().out


def test_validate_refuses_a_step_size_that_is_not_positive(tmp_path, twin_fmus, capsys):
    folder = _system(tmp_path, twin_fmus, step=-0.1)
    assert main(["validate", str(folder)]) == 2
    assert "the step size must be a positive number; got -0.1" in capsys.readouterr().err


def test_run_without_a_step_says_how_to_give_one(tmp_path, twin_fmus, capsys):
    assert main(["run", str(_system(tmp_path, twin_fmus, step=None)), "-q"]) == 2
    assert "no step size: pass --step" in capsys.readouterr().err


def test_info_lists_components_connections_and_parameters(tmp_path, twin_fmus, capsys):
    assert main(["info", str(_system(tmp_path, twin_fmus))]) == 0
    printed = capsys.readouterr().out
    for line in ("system 'pair'", "  gain: Gain.fmu (FMI 2.0", '    interface fmi2-cs (implementation="any")',
                 "  step.y -> gain.u", "  gain.k = 4.0", "direct feedthrough resolved at each step in the order: gain"):
        assert line in printed


def test_pack_makes_an_archive_that_validates(tmp_path, twin_fmus, capsys):
    archive = tmp_path / "pair.ssp"
    assert main(["pack", str(_system(tmp_path, twin_fmus)), "-o", str(archive)]) == 0
    with zipfile.ZipFile(archive) as z:
        assert sorted(z.namelist()) == ["SystemStructure.ssd", "resources/Gain.fmu", "resources/Step.fmu"]
    assert main(["validate", str(archive)]) == 0
    assert "valid — 2 FMUs" in capsys.readouterr().out


def test_pack_types_every_component_for_omsimulator(tmp_path, twin_fmus):
    """OMSimulator reads only Components with type="application/x-fmu-sharedlibrary" (issue 21,
    item 5): pack writes it where the SSD omits it and changes nothing else; the archive runs
    as the folder does."""
    from lxml import etree

    import cosim

    folder = _system(tmp_path, twin_fmus, stop=1.0, step=0.5)
    archive = tmp_path / "pair.ssp"
    assert main(["pack", str(folder), "-o", str(archive)]) == 0
    with zipfile.ZipFile(archive) as z:
        packed = etree.fromstring(z.read("SystemStructure.ssd"))
    ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
    components = packed.findall(".//ssd:Component", ns)
    assert len(components) == 2 and {c.get("type") for c in components} == {"application/x-fmu-sharedlibrary"}
    for c in components:
        del c.attrib["type"]
    original = etree.parse(str(folder / "SystemStructure.ssd")).getroot()
    assert etree.tostring(packed, method="c14n") == etree.tostring(original, method="c14n")
    ours, theirs = cosim.simulate(archive), cosim.simulate(folder)
    assert ours.dtype == theirs.dtype and all((ours[n] == theirs[n]).all() for n in ours.dtype.names)


@pytest.mark.parametrize("argv, message", [
    (["sweep", "{folder}"], "nothing to sweep"),
    (["sweep", "{folder}", "--seeds", "1..2", "--workers", "0"], "--workers 0: give at least 1"),
    (["run", "{folder}", "--signals", "nothing*", "--plot", "x.png", "-q"], "no signal matches 'nothing*'"),
])
def test_wrong_arguments_exit_2_before_anything_runs(tmp_path, twin_fmus, capsys, argv, message):
    folder = _system(tmp_path, twin_fmus)
    assert main([a.format(folder=folder) for a in argv]) == 2
    assert message in capsys.readouterr().err


def test_validate_with_only_a_start_time_invents_no_stop(tmp_path, twin_fmus, capsys):
    """<ssd:DefaultExperiment startTime="5.0"/> (issue 21, item 7): no stop time is reported or checked."""
    folder = _system(tmp_path, twin_fmus, step=None)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('startTime="0" stopTime="1.0"', 'startTime="5.0"'))
    assert main(["validate", str(folder)]) == 0
    assert "no stop time in the SSD (run needs --stop); no step size in the SSD" in capsys.readouterr().out
    assert main(["run", str(folder), "--step", "0.5", "--stop", "6", "-o", str(tmp_path / "o.csv"), "-q"]) == 0
