"""Read an SSP 1.0 system structure: a folder, a bare ``.ssd`` or an ``.ssp`` archive.

The reader is strict.  It checks well-formedness (with line and column), the
SSP 1.0 XML schema (the XSDs shipped with fmpy), and refuses, with a message,
every SSP feature this master does not implement (parameter mappings, signal
dictionaries, non-FMU components, Boolean/Integer/Enumeration mapping
transformations) instead of ignoring it.  Nested systems and system-level
connectors are read here (`read`: XML → `cosim.structure.RawStructure`) and
flattened by `cosim.flatten` into components named by their path (``loop.ctrl``)
and direct connections; `load` is the two in a row.
Files and archives are opened through `cosim.safeio`: no XML entities or DTDs,
archives checked and size-limited before and while they are extracted.

Parameter precedence follows SSP 1.0 (SystemStructureDescription.xsd,
ParameterBindings): later bindings win at the same level, the system level beats
the component level, and a parameter set given on the command line beats both.
"""
from __future__ import annotations

import math
from contextvars import ContextVar
from dataclasses import replace
from pathlib import Path
from urllib.parse import unquote, urlparse

from lxml import etree

from .errors import SetupError
from .flatten import flatten
from .safeio import extract_archive, is_file, parse_xml, temporary_folder
from .structure import (
    Component,
    Connection,
    Connector,
    Experiment,
    ParameterValue,
    RawStructure,
    RawSystem,
    ScenarioFiles,
    SolverOptions,
    SystemStructure,
)
from .units import BASE_UNITS, Unit, check_definition, make_unit

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
    "ssb": "http://ssp-standard.org/SSP1/SystemStructureSignalDictionary",
}
#: Our own annotation (DefaultExperiment/Annotations): step size and algorithm.
GREYFMU_ANNOTATION = "org.greyfmu.simulation"
GREYFMU_NS = "urn:greyfmu:ssp:simulation:1.0"
#: Vendor annotations read for the step size, as other SSP tools write them.
OSP_ANNOTATION = "com.opensimulationplatform"
OMS_ANNOTATION = "org.openmodelica"
#: Our own annotation on a Component (its ssd:Annotations): how the master integrates a Model
#: Exchange FMU (cosim.instances.me), ``<greyfmu:Solver rtol="1e-8" maxStep="0.001"/>``.
SOLVER_ANNOTATION = "org.greyfmu.solver"
SOLVER_NS = "urn:greyfmu:ssp:solver:1.0"

FMU_MIME = "application/x-fmu-sharedlibrary"
VALUE_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary")
SSD_NAME = "SystemStructure.ssd"


# --------------------------------------------------------------------------- files

def load(path: str | Path, max_unpacked_bytes: int | None = None) -> SystemStructure:
    """Read a scenario folder, a ``.ssd`` file or an ``.ssp`` archive and flatten it
    (`read`, then `cosim.flatten.flatten`)."""
    raw = read(path, max_unpacked_bytes)
    try:
        return flatten(raw)
    except BaseException:
        if raw._tmp is not None:
            raw._tmp.cleanup()
        raise


def read(path: str | Path, max_unpacked_bytes: int | None = None) -> RawStructure:
    """Read a scenario folder, a ``.ssd`` file or an ``.ssp`` archive, as nested as written.

    ``max_unpacked_bytes`` limits what an archive may expand to (default: the
    environment variable COSIM_MAX_UNPACKED_BYTES, else 2 GiB; see `cosim.safeio`).
    """
    path = Path(path)
    if not path.exists():
        raise SetupError("no such file or folder.", file=str(path),
                         hint="Give a scenario folder holding SystemStructure.ssd, a .ssd file or an .ssp archive.")
    if path.is_dir():
        ssd = path / SSD_NAME
        if not ssd.is_file():
            found = sorted(p.name for p in path.glob("*.ssd"))
            raise SetupError(f"the folder has no {SSD_NAME}.", file=str(path),
                             hint=(f"It has {', '.join(found)}: pass that file instead." if found else None))
        return _read_ssd(ssd)
    if path.suffix.lower() == ".ssp":
        return _read_archive(path, max_unpacked_bytes)
    if path.suffix.lower() == ".ssd":
        return _read_ssd(path)
    raise SetupError("not an SSP system structure (expected a folder, a .ssd or an .ssp).", file=str(path))


def _read_archive(path: Path, max_unpacked_bytes: int | None = None) -> RawStructure:
    """Extract the archive (checked and size-limited, see `cosim.safeio`) and read its SSD."""
    tmp = temporary_folder("cosim-ssp-")
    try:
        extract_archive(path, Path(tmp.name), max_unpacked_bytes, required=SSD_NAME)
        token = _ARCHIVE_ROOT.set(Path(tmp.name).resolve())
        try:
            structure = _read_ssd(Path(tmp.name) / SSD_NAME, display=f"{path}!{SSD_NAME}")
        finally:
            _ARCHIVE_ROOT.reset(token)
    except BaseException:
        tmp.cleanup()
        raise
    return replace(structure, files=replace(structure.files, archive=path), _tmp=tmp)


_schemas: dict[str, etree.XMLSchema] = {}


def validate_schema(tree: etree._ElementTree | etree._Element, schema_file: str, display: str) -> None:
    """Validate against an SSP 1.0 XSD; the first errors are reported with their lines."""
    if schema_file not in _schemas:
        import fmpy.ssp
        xsd = Path(fmpy.ssp.__file__).parent / "schema" / schema_file
        _schemas[schema_file] = etree.XMLSchema(file=str(xsd))
    schema = _schemas[schema_file]
    if not schema.validate(tree):
        errors = [f"line {err.line}: {err.message.rstrip('.')}" for err in list(schema.error_log)[:5]]
        raise SetupError("does not conform to the SSP 1.0 schema ("
                         f"{schema_file}): " + "; ".join(errors) + ".", file=display)


# --------------------------------------------------------------------------- SSD

def _read_ssd(path: Path, display: str | None = None) -> RawStructure:
    display = display or str(path)
    tree = parse_xml(path, display)
    root = tree.getroot()
    if etree.QName(root).namespace != NS["ssd"] or etree.QName(root).localname != "SystemStructureDescription":
        raise SetupError("the root element is not an SSP 1.0 ssd:SystemStructureDescription "
                         f"(found {root.tag}).", file=display, element=f"line {root.sourceline}")
    validate_schema(tree, "SystemStructureDescription.xsd", display)
    _refuse_unsupported(root, display)

    system = root.find("ssd:System", NS)
    base_dir = path.parent

    start = stop = None
    experiment = root.find("ssd:DefaultExperiment", NS)
    if experiment is not None:
        start = _float_attr(experiment, "startTime", display)
        stop = _float_attr(experiment, "stopTime", display)
    step, step_source, algorithm = _read_step_annotations(root, display)
    return RawStructure(name=root.get("name"), files=ScenarioFiles(path, base_dir, None), display=display,
                        root=_read_system(system, base_dir, display),
                        experiment=Experiment(start, stop, step, step_source, algorithm),
                        units=read_units(root.find("ssd:Units", NS), display))


def _refuse_unsupported(root: etree._Element, display: str) -> None:
    refused = [
        (".//ssd:Elements/ssd:SignalDictionaryReference", "signal dictionaries are not supported"),
        (".//ssd:System/ssd:SignalDictionaries", "signal dictionaries are not supported"),
        (".//ssd:ParameterMapping", "parameter mappings (.ssm) are not supported; rename the parameters in the .ssv"),
        (".//ssc:BooleanMappingTransformation", "Boolean mapping transformations are not supported"),
        (".//ssc:IntegerMappingTransformation", "Integer mapping transformations are not supported"),
        (".//ssc:EnumerationMappingTransformation", "Enumeration mapping transformations are not supported"),
    ]
    for xpath, why in refused:
        found = root.find(xpath, NS)
        if found is not None:
            raise SetupError(why + ".", file=display,
                             element=f"{etree.QName(found).localname} (line {found.sourceline})")


def _read_system(system: etree._Element, base_dir: Path, display: str) -> RawSystem:
    """One ``ssd:System`` and, recursively, the systems in its ``ssd:Elements``, with local names.

    Element names are unique within their system (SSP 1.0, TElement name); geometry and
    annotations of the system are not read.
    """
    name = system.get("name")
    connectors: dict[str, Connector] = {}
    for c in system.iterfind("ssd:Connectors/ssd:Connector", NS):
        conn = _read_connector(c)
        if conn.name in connectors:
            raise SetupError(f"connector '{conn.name}' is declared twice.", file=display,
                             element=f"ssd:System '{name}' (line {system.sourceline})", variable=conn.name)
        connectors[conn.name] = conn
    raw = RawSystem(name=name, line=system.sourceline, connectors=connectors, components={}, systems={},
                    connections=[], parameters=_read_bindings(system, base_dir, display))
    elements = system.find("ssd:Elements", NS)
    for el in (elements if elements is not None else []):
        if not isinstance(el.tag, str):
            continue
        local = etree.QName(el).localname
        element_name = el.get("name")
        if element_name in raw.components or element_name in raw.systems:
            raise SetupError(f"two elements of system '{name}' are named '{element_name}'.", file=display,
                             element=f"ssd:{local} (line {el.sourceline})")
        if local == "System":
            raw.systems[element_name] = _read_system(el, base_dir, display)
        else:
            raw.components[element_name] = _read_component(el, base_dir, display)
        raw.elements.append(element_name)
    raw.connections = [_read_connection(c, display) for c in system.iterfind("ssd:Connections/ssd:Connection", NS)]
    return raw


def _read_component(el: etree._Element, base_dir: Path, display: str) -> Component:
    name = el.get("name")
    where = f"ssd:Component '{name}' (line {el.sourceline})"
    ctype = el.get("type", FMU_MIME)
    if ctype != FMU_MIME:
        raise SetupError(f"component type '{ctype}' is not supported; only FMUs ({FMU_MIME}).",
                         file=display, element=where)
    comp = Component(name=name, source=el.get("source"), line=el.sourceline,
                     implementation=el.get("implementation", "any"))
    for c in el.iterfind("ssd:Connectors/ssd:Connector", NS):
        conn = _read_connector(c)
        if conn.name in comp.connectors:
            raise SetupError(f"connector '{conn.name}' is declared twice.", file=display, element=where)
        comp.connectors[conn.name] = conn
    comp.parameters = _read_bindings(el, base_dir, display)
    comp.solver = _read_solver_annotation(el, display)
    return comp


def _read_solver_annotation(component: etree._Element, display: str) -> SolverOptions | None:
    """A Component's ``org.greyfmu.solver`` annotation: one greyfmu:Solver element with
    ``rtol`` and/or ``maxStep`` (positive numbers); anything else is refused."""
    for ann in component.iterfind("ssd:Annotations/ssc:Annotation", NS):
        if ann.get("type") != SOLVER_ANNOTATION:
            continue
        where = f"ssc:Annotation type='{SOLVER_ANNOTATION}' (line {ann.sourceline})"
        children = [c for c in ann if isinstance(c.tag, str)]
        if len(children) != 1 or etree.QName(children[0]) != etree.QName(SOLVER_NS, "Solver"):
            raise SetupError(f"expected one <greyfmu:Solver xmlns:greyfmu=\"{SOLVER_NS}\" rtol=\"...\" "
                             "maxStep=\"...\"/> element.", file=display, element=where)
        solver = children[0]
        unknown = sorted(set(solver.attrib) - {"rtol", "maxStep"})
        if unknown:
            raise SetupError(f"unknown attribute(s) {', '.join(unknown)} of greyfmu:Solver; it has rtol and "
                             "maxStep.", file=display, element=where)
        values = {a: _float_attr(solver, a, display) for a in ("rtol", "maxStep")}
        for attr, value in values.items():
            if value is not None and not (0.0 < value < float("inf")):
                raise SetupError(f"{attr}='{solver.get(attr)}' must be a positive number.", file=display,
                                 element=where)
        return SolverOptions(rtol=values["rtol"], max_step=values["maxStep"], file=display, element=where)
    return None


def _read_connector(c: etree._Element) -> Connector:
    type_el = next((t for t in c if isinstance(t.tag, str) and etree.QName(t).namespace == NS["ssc"]
                    and etree.QName(t).localname in VALUE_TYPES), None)
    return Connector(name=c.get("name"), kind=c.get("kind"),
                     type=etree.QName(type_el).localname if type_el is not None else None,
                     unit=type_el.get("unit") if type_el is not None else None, line=c.sourceline)


def _read_connection(c: etree._Element, display: str) -> Connection:
    line = c.sourceline
    factor, offset, has = 1.0, 0.0, False
    lt = c.find("ssc:LinearTransformation", NS)
    if lt is not None:
        has = True
        factor = _float_attr(lt, "factor", display, default=1.0)
        offset = _float_attr(lt, "offset", display, default=0.0)
    suppress = c.get("suppressUnitConversion", "false") in ("true", "1")
    # an empty element name is the enclosing system, as an omitted one (OMSimulator writes
    # startElement="" for a system's own connector; the schema's xs:string accepts it)
    return Connection(c.get("startElement") or None, c.get("startConnector"), c.get("endElement") or None,
                      c.get("endConnector"), factor, offset, has, suppress, line)


def _float_attr(el: etree._Element, name: str, display: str, default: float | None = None) -> float | None:
    text = el.get(name)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not math.isfinite(value):  # NaN, INF and 1e400 are xs:double, not usable numbers
        raise SetupError(f"attribute {name}='{text}' is not a finite number.", file=display,
                         element=f"{etree.QName(el).localname} (line {el.sourceline})")
    return value


def _read_bindings(owner: etree._Element, base_dir: Path, display: str) -> list[ParameterValue]:
    values: list[ParameterValue] = []
    for binding in owner.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
        where = f"ssd:ParameterBinding (line {binding.sourceline})"
        btype = binding.get("type", "application/x-ssp-parameter-set")
        if btype != "application/x-ssp-parameter-set":
            raise SetupError(f"parameter binding type '{btype}' is not supported.", file=display, element=where)
        if binding.get("sourceBase", "SSD") != "SSD":
            raise SetupError("sourceBase='component' is not supported; give the .ssv relative to the SSD.",
                             file=display, element=where)
        prefix = binding.get("prefix", "")
        source = binding.get("source")
        if source is not None:
            try:
                ssv = resolve_uri(source, base_dir)
            except SetupError as e:
                raise SetupError(e.detail, file=display, element=where) from None
            if not is_file(ssv):
                raise SetupError(f"parameter set '{source}' not found (looked at {ssv}).", file=display,
                                 element=where)
            parsed = read_ssv(ssv)
        else:
            inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            if inline is None:
                raise SetupError("a parameter binding needs a source or inline ssd:ParameterValues.",
                                 file=display, element=where)
            # the SSD schema lets ssd:ParameterValues hold anything: check the inline set as an .ssv is
            validate_schema(inline, "SystemStructureParameterValues.xsd", display)
            parsed = _read_parameter_set(inline, display)
        values.extend(replace(p, name=prefix + p.name) for p in parsed)
    return values


def read_ssv(path: str | Path) -> list[ParameterValue]:
    """Read an ``.ssv`` parameter set file (SystemStructureParameterValues.xsd)."""
    path = Path(path)
    tree = parse_xml(path)
    root = tree.getroot()
    if etree.QName(root).namespace != NS["ssv"] or etree.QName(root).localname != "ParameterSet":
        raise SetupError(f"the root element is not an SSP 1.0 ssv:ParameterSet (found {root.tag}).",
                         file=str(path), element=f"line {root.sourceline}")
    validate_schema(tree, "SystemStructureParameterValues.xsd", str(path))
    return _read_parameter_set(root, str(path))


def _read_parameter_set(pset: etree._Element, display: str) -> list[ParameterValue]:
    values = []
    units = read_units(pset.find("ssv:Units", NS), display)
    for p in pset.iterfind("ssv:Parameters/ssv:Parameter", NS):
        v = next(t for t in p if isinstance(t.tag, str) and etree.QName(t).localname in VALUE_TYPES)
        kind = etree.QName(v).localname
        text = v.get("value")
        if kind == "Real":
            value: float | int | bool | str = float(text)
        elif kind == "Integer":
            value = int(text)
        elif kind == "Boolean":
            value = text in ("true", "1")
        elif kind in ("String", "Enumeration"):  # an Enumeration value is an item name (SSP 1.0 ssv)
            value = text
        else:
            raise SetupError(f"{kind} parameter values are not supported.", file=display,
                             element=f"ssv:Parameter (line {p.sourceline})", variable=p.get("name"))
        values.append(ParameterValue(p.get("name"), kind, value, display, p.sourceline,
                                     unit=v.get("unit") if kind == "Real" else None, units=units))
    return values


def read_units(units: etree._Element | None, display: str) -> dict[str, Unit]:
    """The ``ssc:Unit`` definitions of an ``ssd:Units`` or ``ssv:Units`` element (SSP 1.0
    SystemStructureCommon.xsd TUnits: a name and a BaseUnit with exponents, factor, offset)."""
    found: dict[str, Unit] = {}
    for u in (units if units is not None else []):
        if not isinstance(u.tag, str):
            continue
        name = u.get("name")
        where = f"ssc:Unit '{name}' (line {u.sourceline})"
        if name in found:
            raise SetupError(f"unit '{name}' is defined twice.", file=display, element=where)
        base = u.find("ssc:BaseUnit", NS)
        if base is None:
            raise SetupError("a unit needs an ssc:BaseUnit.", file=display, element=where)
        exponents = {}
        for attr in BASE_UNITS:
            text = base.get(attr, "0")
            try:
                exponents[attr] = int(text)
            except ValueError:
                raise SetupError(f"exponent {attr}='{text}' is not an integer.", file=display,
                                 element=where) from None
        found[name] = make_unit(name, display, _float_attr(base, "factor", display, default=1.0),
                                _float_attr(base, "offset", display, default=0.0), **exponents)
        check_definition(found[name], file=display, element=where)
    return found


#: The extraction folder of the .ssp being read, if any: its SSD may refer only to its own members.
_ARCHIVE_ROOT: ContextVar[Path | None] = ContextVar("cosim_archive_root", default=None)


def resolve_uri(uri: str, base_dir: Path, archive_root: Path | None = None) -> Path:
    """Resolve a relative (or file:) URI of an SSD against its folder.  Inside an ``.ssp``
    (``archive_root``, by default the archive being read) the result must be a member of the
    archive: an archive from elsewhere must not make the master read ``/etc/passwd`` or
    ``../../secret`` (SSP 1.0 §2.2: an archive's URIs are relative to its root)."""
    if "\0" in unquote(uri):  # %00: no file name holds a NUL (os calls raise ValueError on it)
        raise SetupError(f"'{uri}' holds a NUL byte (%00), which no file name can hold.")
    parsed = urlparse(uri)
    if parsed.scheme == "file":
        if parsed.netloc not in ("", "localhost"):
            raise SetupError(f"file URI with a host ('{parsed.netloc}') is not supported ({uri}); "
                             "use a relative path.")
        path = Path(unquote(parsed.path))
    elif parsed.scheme and len(parsed.scheme) > 1:
        raise SetupError(f"URI scheme '{parsed.scheme}:' is not supported ({uri}); use a relative path.")
    else:
        path = base_dir / unquote(uri)
    root = archive_root if archive_root is not None else _ARCHIVE_ROOT.get()
    if root is not None and not path.resolve().is_relative_to(root):
        raise SetupError(f"'{uri}' points outside the .ssp archive; an archive may refer only to its own "
                         "members (relative paths inside it).")
    return path


def _read_step_annotations(root: etree._Element, display: str) -> tuple[float | None, str | None, str | None]:
    """The step size from our own annotation, else OSP's, else OpenModelica's (nested systems' ignored)."""
    found: dict[str, tuple[float | None, str | None]] = {}
    for ann in root.iter(f"{{{NS['ssc']}}}Annotation"):
        if sum(1 for a in ann.iterancestors(f"{{{NS['ssd']}}}System")) > 1:
            continue
        kind = ann.get("type")
        for el in ann.iter():
            if not isinstance(el.tag, str):
                continue
            local = etree.QName(el).localname
            if kind == GREYFMU_ANNOTATION and local == "Simulation":
                found[kind] = (_float_attr(el, "stepSize", display), el.get("algorithm"))
            elif kind == OSP_ANNOTATION and local == "FixedStepAlgorithm":
                found[kind] = (_float_attr(el, "baseStepSize", display), None)
            elif kind == OMS_ANNOTATION and local == "FixedStepMaster":
                found[kind] = (_float_attr(el, "stepSize", display), None)
    for kind in (GREYFMU_ANNOTATION, OSP_ANNOTATION, OMS_ANNOTATION):
        if kind in found and found[kind][0] is not None:
            step, _ = found[kind]
            return step, f"annotation {kind}", found.get(GREYFMU_ANNOTATION, (None, None))[1]
    return None, None, found.get(GREYFMU_ANNOTATION, (None, None))[1]

