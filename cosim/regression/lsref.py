"""``cosim verify X.fmu``: run the reference experiments an FMU carries (FMI-LS-REF) and compare.

FMI Layered Standard References, tag v1.0.0-beta.1 of github:modelica/fmi-ls-ref: the manifest
``extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml`` lists related files; those with role
``experiment`` (or ``experiment/<sub-role>``) and type ``application/x-ma-hs-experiments`` (the
MA-HS-Experiments format, github:modelica/ma-hs-experiments; the older ``x-ma-ls-experiments``
name of the draft's appendix is read too) are run.  Each ``<Experiment>``: start, stop and step
from its ``<TransientSimulation>`` (or, as the format's document and example still write them,
from attributes of ``<Experiment>``), ``<Parameters>`` an SSV applied by variable name,
``<Stimuli>`` a CSV input table, ``<References>`` the CSV to compare with.  Every source is a
URI relative to the file naming it and must name a member of the FMU (no scheme, nothing outside
the archive); a file listed but absent is an error naming it.

The comparison is `cosim.regression.engine.compare` on the reference's time points: with the
tolerances of an ``org.greyfmu.comparison`` annotation (`greyfmu.lsref` writes one into our
FMUs), else with the FMI cross-check rule (`cosim.regression.tube.cross_check_band`), the
rule the FMI community applies to another tool's results.  Neither document defines a
comparison of its own.
"""
from __future__ import annotations

import posixpath
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlsplit

from ..errors import SetupError
from ..safeio import parse_xml_bytes, read_member
from .engine import Verdict, compare
from .tolerances import Tolerance

FOLDER = "extra/org.fmi-standard.fmi-ls-ref"
MANIFEST = f"{FOLDER}/fmi-ls-manifest.xml"
EXPERIMENT_TYPES = ("application/x-ma-hs-experiments", "application/x-ma-ls-experiments")
ANNOTATION = "org.greyfmu.comparison"


@dataclass(frozen=True)
class Experiment:
    """One ``<Experiment>`` of an experiments file, its files named as archive members."""
    source: str
    name: str
    description: str
    start: float | None
    stop: float | None
    step: float | None
    parameters: str | None
    stimuli: str | None
    references: str | None
    tolerances: dict[str, Tolerance] = field(default_factory=dict)

    @property
    def label(self) -> str:
        return f"{self.name} ({self.source})"


@dataclass(frozen=True)
class Outcome:
    """An experiment run and compared: its verdicts, or why it could not be run."""
    experiment: Experiment
    verdicts: list[Verdict]
    error: str = ""

    @property
    def passed(self) -> bool:
        return not self.error and all(v.passed for v in self.verdicts)


def _member(base: str, uri: str, fmu: Path, element: str) -> str:
    """The archive member a relative URI names, seen from the member ``base``."""
    parts = urlsplit(uri)
    if parts.scheme or parts.netloc or uri.startswith("/"):
        raise SetupError(f"'{uri}' is not a relative URI inside the FMU; cosim verify reads only what the FMU "
                         "carries.", file=str(fmu), element=element)
    name = posixpath.normpath(posixpath.join(posixpath.dirname(base), unquote(parts.path)))
    if name.startswith("../") or name == "..":
        raise SetupError(f"'{uri}' leaves the FMU archive.", file=str(fmu), element=element)
    return name


def _float(node, name: str, fmu: Path, where: str) -> float | None:
    text = node.get(name) if node is not None else None
    if text is None:
        return None
    try:
        return float(text)
    except ValueError:
        raise SetupError(f"{name}='{text}' is not a number.", file=str(fmu), element=where) from None


def _tolerances(node, fmu: Path, where: str) -> dict[str, Tolerance]:
    found = {}
    for annotation in node.iterfind("Annotations/Annotation"):
        if annotation.get("type") != ANNOTATION:
            continue
        for row in annotation.iterfind("Comparison/Tolerance"):
            found[row.get("signal")] = Tolerance(*(_float(row, f, fmu, where) or 0.0 for f in ("rtol", "atol", "time")))
    return found


def _read_experiments(fmu: Path, source: str) -> list[Experiment]:
    root = parse_xml_bytes(read_member(fmu, source, str(fmu), MANIFEST), f"{fmu}!/{source}").getroot()
    if root.tag != "Experiments":
        raise SetupError(f"the root element is <{root.tag}>, not <Experiments>.", file=str(fmu), element=source)
    experiments = []
    for node in root.iterfind("Experiment"):
        label = f"{source} Experiment '{node.get('name')}'"
        timing = node.find("TransientSimulation")
        timing = timing if timing is not None else node

        def file(tag: str) -> str | None:
            child = node.find(tag)
            if child is None:
                return None
            if child.get("source") is None:
                raise SetupError(f"<{tag}> has no source.", file=str(fmu), element=label)
            return _member(source, child.get("source"), fmu, f"{label} <{tag}>")

        experiments.append(Experiment(source, node.get("name") or "?", node.get("description") or "",
                                      _float(timing, "startTime", fmu, label), _float(timing, "stopTime", fmu, label),
                                      _float(timing, "stepSize", fmu, label), file("Parameters"), file("Stimuli"),
                                      file("References"), _tolerances(node, fmu, label)))
    return experiments


def read_experiments(fmu: str | Path) -> list[Experiment]:
    """The experiments an FMU's FMI-LS-REF manifest lists (module docstring); a `SetupError`
    saying so when the FMU carries none."""
    import zipfile

    fmu = Path(fmu)
    try:
        with zipfile.ZipFile(fmu) as archive:
            has_manifest = MANIFEST in archive.namelist()
    except (zipfile.BadZipFile, OSError) as e:
        raise SetupError(f"not an FMU (a zip archive): {e}.", file=str(fmu)) from None
    if not has_manifest:
        raise SetupError(f"the FMU carries no FMI-LS-REF reference experiments (no {MANIFEST}); nothing to verify. "
                         "FMI-LS-REF (github:modelica/fmi-ls-ref) puts them there; greyfmu's FMUs carry one each.",
                         file=str(fmu))
    root = parse_xml_bytes(read_member(fmu, MANIFEST, str(fmu), MANIFEST), f"{fmu}!/{MANIFEST}").getroot()
    experiments = []
    for related in root.iterfind("Related"):
        role = related.get("role") or ""
        if role.split("/")[0] != "experiment" or related.get("type") not in EXPERIMENT_TYPES:
            continue
        source = _member(MANIFEST, related.get("source") or "", fmu, f"{MANIFEST} <Related role='{role}'>")
        experiments += _read_experiments(fmu, source)
    if not experiments:
        raise SetupError(f"the FMI-LS-REF manifest lists no experiment of type {EXPERIMENT_TYPES[0]}; nothing to "
                         "verify.", file=str(fmu), element=MANIFEST)
    return experiments


def _write(fmu: Path, member: str, folder: Path, element: str) -> Path:
    path = folder / posixpath.basename(member)
    path.write_bytes(read_member(fmu, member, str(fmu), element))
    return path


def run_experiment(fmu: Path, experiment: Experiment, folder: Path) -> Outcome:
    """Run one experiment with cosim (`cosim.run.simulation.simulate_fmu`) and compare with its references."""
    from ..errors import CosimError
    from ..read.ssp import read_ssv
    from ..record.results import read
    from ..run.simulation import simulate_fmu

    if experiment.references is None:
        return Outcome(experiment, [], "it names no <References>, so there is nothing to compare")
    try:
        reference = read(_write(fmu, experiment.references, folder, f"{experiment.label} <References>"))
        starts = {}
        if experiment.parameters:
            ssv = _write(fmu, experiment.parameters, folder, f"{experiment.label} <Parameters>")
            starts = {p.name: p.value for p in read_ssv(ssv)}
        stimuli = _write(fmu, experiment.stimuli, folder, f"{experiment.label} <Stimuli>") if experiment.stimuli \
            else None
        options = {"start_time": experiment.start, "stop_time": experiment.stop, "step_size": experiment.step}
        result = simulate_fmu(fmu, start_values=starts, input_file=stimuli,
                              **{k: v for k, v in options.items() if v is not None})
    except CosimError as e:
        return Outcome(experiment, [], f"{e.code.value}: {e}")
    signals = [n for n in reference.dtype.names if n != "time"]
    if experiment.tolerances:
        tolerances = {name: tol for name, tol in experiment.tolerances.items() if name in signals}
        return Outcome(experiment, compare(reference, result, signals=signals, tolerances=tolerances))
    return Outcome(experiment, compare(reference, result, signals=signals, mode="fmi-cross-check"))


def verify(fmu: str | Path, folder: Path) -> list[Outcome]:
    """Every experiment of the FMU run and compared (``folder``: where its files are written)."""
    return [run_experiment(Path(fmu), experiment, folder) for experiment in read_experiments(fmu)]


def summary(outcomes: Sequence[Outcome]) -> list[str]:
    """Lines for a person: each experiment's verdict, each failing signal's."""
    lines = []
    for o in outcomes:
        e = o.experiment
        state = "passed" if o.passed else "FAILED"
        lines.append(f"experiment {e.label}: {state}" + (f" ({o.error})" if o.error else
                                                           f", {sum(v.passed for v in o.verdicts)} of "
                                                           f"{len(o.verdicts)} signals within tolerance"))
        lines += [f"  {v.describe()}" for v in o.verdicts if not v.passed]
    return lines
