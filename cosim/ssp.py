"""Read an SSP 1.0 system structure: a folder, a bare ``.ssd`` or an ``.ssp`` archive.

The reader is strict.  It checks well-formedness (with line and column), the
SSP 1.0 XML schema (the XSDs shipped with fmpy), and refuses, with a message,
every SSP feature this master does not implement (parameter mappings, signal
dictionaries, nested systems, system-level connectors, non-FMU components,
Boolean/Integer/Enumeration mapping transformations) instead of ignoring it.

Parameter precedence follows SSP 1.0 (SystemStructureDescription.xsd,
ParameterBindings): later bindings win at the same level, the system level beats
the component level, and a parameter set given on the command line beats both.
"""
from __future__ import annotations

import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from urllib.parse import unquote, urlparse

from lxml import etree

from .errors import SetupError

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

FMU_MIME = "application/x-fmu-sharedlibrary"
VALUE_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary")
SSD_NAME = "SystemStructure.ssd"


@dataclass
class Connector:
    name: str
    kind: str
    type: str | None
    unit: str | None
    line: int


@dataclass
class ParameterValue:
    """One value from a parameter set; ``name`` is as it resolves at its binding level."""
    name: str
    type: str
    value: float | int | bool | str
    file: str
    line: int


@dataclass
class Component:
    name: str
    source: str
    line: int
    connectors: dict[str, Connector] = field(default_factory=dict)
    parameters: list[ParameterValue] = field(default_factory=list)
    fmu_path: Path | None = None


@dataclass
class Connection:
    start_element: str
    start_connector: str
    end_element: str
    end_connector: str
    factor: float
    offset: float
    has_transformation: bool
    suppress_unit_conversion: bool
    line: int

    def describe(self) -> str:
        return (f"connection {self.start_element}.{self.start_connector} -> "
                f"{self.end_element}.{self.end_connector} (line {self.line})")


@dataclass
class SystemStructure:
    name: str
    system_name: str
    ssd_file: Path
    base_dir: Path
    components: dict[str, Component]
    connections: list[Connection]
    parameters: list[ParameterValue]
    start_time: float | None
    stop_time: float | None
    step_size: float | None
    step_size_source: str | None
    algorithm: str | None
    archive: Path | None = None
    _tmp: tempfile.TemporaryDirectory | None = field(default=None, repr=False)

    def close(self) -> None:
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None


# --------------------------------------------------------------------------- files

def load(path: str | Path) -> SystemStructure:
    """Read a scenario folder, a ``.ssd`` file or an ``.ssp`` archive."""
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
        return _read_archive(path)
    if path.suffix.lower() == ".ssd":
        return _read_ssd(path)
    raise SetupError("not an SSP system structure (expected a folder, a .ssd or an .ssp).", file=str(path))


def _read_archive(path: Path) -> SystemStructure:
    try:
        archive = zipfile.ZipFile(path)
    except zipfile.BadZipFile as e:
        raise SetupError(f"not a zip archive ({e}).", file=str(path)) from None
    with archive:
        for info in archive.infolist():
            check_member_name(info.filename, path)
        names = archive.namelist()
        if SSD_NAME not in names:
            raise SetupError(f"the archive has no {SSD_NAME} at its root.", file=str(path),
                             hint=f"Members: {', '.join(names[:10])}.")
        tmp = tempfile.TemporaryDirectory(prefix="cosim-ssp-")
        archive.extractall(tmp.name)
    structure = _read_ssd(Path(tmp.name) / SSD_NAME, display=f"{path}!{SSD_NAME}")
    structure.archive = path
    structure._tmp = tmp
    return structure


def check_member_name(name: str, archive: Path) -> None:
    """Refuse archive members that are absolute or escape the archive (``../``)."""
    posix = PurePosixPath(name.replace("\\", "/"))
    if posix.is_absolute() or (len(name) > 1 and name[1] == ":"):
        raise SetupError(f"archive member '{name}' has an absolute path; SSP members must be relative.",
                         file=str(archive))
    if ".." in posix.parts:
        raise SetupError(f"archive member '{name}' escapes the archive ('..'); refusing to extract it.",
                         file=str(archive))


def parse_xml(path: Path, display: str | None = None) -> etree._ElementTree:
    """Parse with line numbers; a file that is not well formed names line and column."""
    try:
        return etree.parse(str(path), etree.XMLParser(remove_comments=True))
    except etree.XMLSyntaxError as e:
        line, col = e.position if e.position else (e.lineno, 0)
        raise SetupError(f"XML is not well formed at line {line}, column {col}: {e.msg}.",
                         file=display or str(path)) from None
    except OSError as e:
        raise SetupError(f"cannot read the file ({e}).", file=display or str(path)) from None


_schemas: dict[str, etree.XMLSchema] = {}


def validate_schema(tree: etree._ElementTree, schema_file: str, display: str) -> None:
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

def _read_ssd(path: Path, display: str | None = None) -> SystemStructure:
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
    components: dict[str, Component] = {}
    elements = system.find("ssd:Elements", NS)
    for el in (elements if elements is not None else []):
        if not isinstance(el.tag, str):
            continue
        comp = _read_component(el, base_dir, display)
        if comp.name in components:
            raise SetupError(f"two components are named '{comp.name}'.", file=display,
                             element=f"ssd:Component (line {el.sourceline})")
        components[comp.name] = comp

    connections = [_read_connection(c, display) for c in system.iterfind("ssd:Connections/ssd:Connection", NS)]
    parameters = _read_bindings(system, base_dir, display)

    start = stop = None
    experiment = root.find("ssd:DefaultExperiment", NS)
    if experiment is not None:
        start = _float_attr(experiment, "startTime", display)
        stop = _float_attr(experiment, "stopTime", display)
    step, step_source, algorithm = _read_step_annotations(root, display)
    return SystemStructure(name=root.get("name"), system_name=system.get("name"), ssd_file=path,
                           base_dir=base_dir, components=components, connections=connections,
                           parameters=parameters, start_time=start, stop_time=stop, step_size=step,
                           step_size_source=step_source, algorithm=algorithm)


def _refuse_unsupported(root: etree._Element, display: str) -> None:
    refused = [
        ("ssd:System/ssd:Elements/ssd:System", "nested systems are not supported by this master yet"),
        ("ssd:System/ssd:Elements/ssd:SignalDictionaryReference", "signal dictionaries are not supported"),
        ("ssd:System/ssd:SignalDictionaries", "signal dictionaries are not supported"),
        (".//ssd:ParameterMapping", "parameter mappings (.ssm) are not supported; rename the parameters in the .ssv"),
        (".//ssc:BooleanMappingTransformation", "Boolean mapping transformations are not supported"),
        (".//ssc:IntegerMappingTransformation", "Integer mapping transformations are not supported"),
        (".//ssc:EnumerationMappingTransformation", "Enumeration mapping transformations are not supported"),
        ("ssd:System/ssd:Connectors/ssd:Connector",
         "system-level connectors are not supported (they only matter for nested systems)"),
    ]
    for xpath, why in refused:
        found = root.find(xpath, NS)
        if found is not None:
            raise SetupError(why + ".", file=display,
                             element=f"{etree.QName(found).localname} (line {found.sourceline})")


def _read_component(el: etree._Element, base_dir: Path, display: str) -> Component:
    name = el.get("name")
    where = f"ssd:Component '{name}' (line {el.sourceline})"
    ctype = el.get("type", FMU_MIME)
    if ctype != FMU_MIME:
        raise SetupError(f"component type '{ctype}' is not supported; only FMUs ({FMU_MIME}).",
                         file=display, element=where)
    implementation = el.get("implementation", "any")
    if implementation == "ModelExchange":
        raise SetupError("implementation='ModelExchange' is not supported; this master runs "
                         "Co-Simulation FMUs.", file=display, element=where)
    comp = Component(name=name, source=el.get("source"), line=el.sourceline)
    for c in el.iterfind("ssd:Connectors/ssd:Connector", NS):
        conn = _read_connector(c)
        if conn.name in comp.connectors:
            raise SetupError(f"connector '{conn.name}' is declared twice.", file=display, element=where)
        comp.connectors[conn.name] = conn
    comp.parameters = _read_bindings(el, base_dir, display)
    return comp


def _read_connector(c: etree._Element) -> Connector:
    type_el = next((t for t in c if isinstance(t.tag, str) and etree.QName(t).namespace == NS["ssc"]
                    and etree.QName(t).localname in VALUE_TYPES), None)
    return Connector(name=c.get("name"), kind=c.get("kind"),
                     type=etree.QName(type_el).localname if type_el is not None else None,
                     unit=type_el.get("unit") if type_el is not None else None, line=c.sourceline)


def _read_connection(c: etree._Element, display: str) -> Connection:
    line = c.sourceline
    if c.get("startElement") is None or c.get("endElement") is None:
        raise SetupError("connections to system-level connectors (no startElement/endElement) are not "
                         "supported.", file=display, element=f"ssd:Connection (line {line})")
    factor, offset, has = 1.0, 0.0, False
    lt = c.find("ssc:LinearTransformation", NS)
    if lt is not None:
        has = True
        factor = _float_attr(lt, "factor", display, default=1.0)
        offset = _float_attr(lt, "offset", display, default=0.0)
    suppress = c.get("suppressUnitConversion", "false") in ("true", "1")
    return Connection(c.get("startElement"), c.get("startConnector"), c.get("endElement"),
                      c.get("endConnector"), factor, offset, has, suppress, line)


def _float_attr(el: etree._Element, name: str, display: str, default: float | None = None) -> float | None:
    text = el.get(name)
    if text is None:
        return default
    try:
        return float(text)
    except ValueError:
        raise SetupError(f"attribute {name}='{text}' is not a number.", file=display,
                         element=f"{etree.QName(el).localname} (line {el.sourceline})") from None


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
            ssv = resolve_uri(source, base_dir)
            if not ssv.is_file():
                raise SetupError(f"parameter set '{source}' not found (looked at {ssv}).", file=display,
                                 element=where)
            parsed = read_ssv(ssv)
        else:
            inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            if inline is None:
                raise SetupError("a parameter binding needs a source or inline ssd:ParameterValues.",
                                 file=display, element=where)
            parsed = _read_parameter_set(inline, display)
        values.extend(ParameterValue(prefix + p.name, p.type, p.value, p.file, p.line) for p in parsed)
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
        elif kind == "String":
            value = text
        else:
            raise SetupError(f"{kind} parameter values are not supported.", file=display,
                             element=f"ssv:Parameter (line {p.sourceline})", variable=p.get("name"))
        values.append(ParameterValue(p.get("name"), kind, value, display, p.sourceline))
    return values


def resolve_uri(uri: str, base_dir: Path) -> Path:
    """Resolve a relative (or file:) URI of an SSD against its folder."""
    parsed = urlparse(uri)
    if parsed.scheme == "file":
        return Path(unquote(parsed.path))
    if parsed.scheme and len(parsed.scheme) > 1:
        raise SetupError(f"URI scheme '{parsed.scheme}:' is not supported ({uri}); use a relative path.")
    return base_dir / unquote(uri)


def _read_step_annotations(root: etree._Element, display: str) -> tuple[float | None, str | None, str | None]:
    """The step size from our own annotation, else OSP's, else OpenModelica's."""
    found: dict[str, tuple[float | None, str | None]] = {}
    for ann in root.iter(f"{{{NS['ssc']}}}Annotation"):
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

