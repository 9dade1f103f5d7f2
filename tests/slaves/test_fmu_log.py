"""The FMU-log bridge (greyfmu/forwarding.py, wrapped around build/advance/retune in fmus/_slave.py).

greyfmu's warnings reach the FMU log of the instance that caused them, for any slave: here a
GainScheduledPID whose slave has no logging code of its own, through a real FMU under fmpy.
"""

import logging
import warnings

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from greyfmu.forwarding import forward_warnings


def test_forward_warnings_passes_greyfmu_records_and_python_warnings_only_inside_the_block():
    got = []
    with forward_warnings(got.append):
        logging.getLogger("greyfmu.control.gpc").warning("QP %s", "infeasible")
        logging.getLogger("greyfmu.control.gpc").info("not a warning")
        logging.getLogger("elsewhere").warning("not greyfmu's")
        warnings.warn("design outside the advice")
    logging.getLogger("greyfmu.control.gpc").warning("after the block")
    assert got == ["QP infeasible", "design outside the advice"]


def test_a_slave_without_logging_code_forwards_its_controllers_warning(built_fmus, tmp_path, capfd):
    """ITAE law (law = 4): a process time constant T = -1 is refused; the PID holds its gains and says so."""
    path = built_fmus["GainScheduledPID"]
    description = read_model_description(path)
    refs = {v.name: v.valueReference for v in description.modelVariables}
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=extract(path, tmp_path),
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName="gs")
    fmu.instantiate(loggingOn=True)
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setInteger([refs["law"]], [4])
        fmu.exitInitializationMode()
        fmu.setReal([refs["r"]], [1.0])
        fmu.doStep(0.0, 1.0)
        gains = fmu.getReal([refs["Kc"], refs["Ti"]])
        capfd.readouterr()
        fmu.setReal([refs["T"]], [-1.0])
        fmu.doStep(1.0, 1.0)
        assert fmu.getReal([refs["Kc"], refs["Ti"]]) == gains
        log = capfd.readouterr().out
        assert "gs: GainScheduledPID: scheduling variable refused" in log and "time constant T must be" in log
        fmu.terminate()
    finally:
        fmu.freeInstance()
