"""Read an SSP 1.0 or 2.0 system structure: a folder, a bare ``.ssd`` or an ``.ssp`` archive.

The reader is strict.  It checks well-formedness (with line and column), the
SSP 1.0 XML schema (the XSDs shipped with fmpy), and refuses, with a message,
every SSP feature this master does not implement (non-FMU components, for one)
instead of ignoring it.  Signal dictionaries and their references are read into the raw
systems and wired by `cosim.read.flatten`.  SSP 2.0 documents (`as_ssp1`) are read as
SSP 1.0 with the FMI 3.0 data types; what else 2.0 adds is refused by element and
line.  Parameter mappings (``.ssm`` files and inline ``ssm:ParameterMapping``) rename and transform
a binding's values as they are read (`cosim.read.mapping`): after this module a mapped
value is a value like any other, but for a LinearTransformation that waits for the
unit conversion in `cosim.plan.parameters`.  Nested systems and system-level
connectors are read here (`read`: XML → `cosim.model.structure.RawStructure`) and
flattened by `cosim.read.flatten` into components named by their path (``loop.ctrl``)
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

from ..errors import SetupError
from .flatten import flatten
from .mapping import apply_mapping
from ..safeio import extract_archive, is_file, parse_xml, parse_xml_bytes, read_member, temporary_folder
from ..model.structure import (
    Component,
    ComponentBinding,
    Connection,
    Connector,
    Experiment,
    MappingEntry,
    ParameterValue,
    RawStructure,
    RawSystem,
    ScenarioFiles,
    SignalDictionary,
    SignalReference,
    SolverOptions,
    SystemStructure,
)
from ..model.frozen import FrozenMap
from ..model.transforms import Affine, MappingTable, Table
from ..model.units import BASE_UNITS, Unit, check_definition, make_unit

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
#: Exchange FMU (cosim.run.instances.me), ``<greyfmu:Solver rtol="1e-8" maxStep="0.001"/>``.
SOLVER_ANNOTATION = "org.greyfmu.solver"
SOLVER_NS = "urn:greyfmu:ssp:solver:1.0"

FMU_MIME = "application/x-fmu-sharedlibrary"
PARAMETER_SET_MIME = "application/x-ssp-parameter-set"
PARAMETER_MAPPING_MIME = "application/x-ssp-parameter-mapping"
SIGNAL_DICTIONARY_MIME = "application/x-ssp-signal-dictionary"
#: the root elements of the SSP file formats, each with a ``version`` attribute
VERSIONED_ROOTS = {(NS["ssd"], "SystemStructureDescription"), (NS["ssv"], "ParameterSet"),
                   (NS["ssm"], "ParameterMapping"), (NS["ssb"], "SignalDictionary")}
#: the FMI 3.0 data types SSP 2.0 adds, as the SSP 1.0 type the master reads them as: a Float64
#: variable of an FMI 3.0 FMU already takes an ssv:Real, an Int32 one an ssv:Integer (cosim.read.description)
SSP2_TYPES = {"Float64": "Real", "Float32": "Real", **{f"{u}Int{n}": "Integer" for u in ("", "U")
                                                      for n in (8, 16, 32, 64)}}
VALUE_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary")
SSD_NAME = "SystemStructure.ssd"


# --------------------------------------------------------------------------- files

def load(path: str | Path, max_unpacked_bytes: int | None = None) -> SystemStructure:
    """Read a scenario folder, a ``.ssd`` file or an ``.ssp`` archive and flatten it
    (`read`, then `cosim.read.flatten.flatten`)."""
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


def validate_schema(tree: etree._ElementTree | etree._Element, schema_file: str, display: str,
                    ssp2: bool = False) -> None:
    """Validate against an SSP 1.0 XSD; the first errors are reported with their lines.  An SSP 2.0
    document is validated as `as_ssp1` reads it: what SSP 2.0 adds beyond its new data types fails
    here, named by element and line."""
    if schema_file not in _schemas:
        import fmpy.ssp
        xsd = Path(fmpy.ssp.__file__).parent / "schema" / schema_file
        _schemas[schema_file] = etree.XMLSchema(file=str(xsd))
    schema = _schemas[schema_file]
    if not schema.validate(tree):
        errors = [f"line {err.line}: {_prefixed(err.message.rstrip('.'))}" for err in list(schema.error_log)[:5]]
        what = ("uses SSP 2.0 content this master cannot run (checked as SSP 1.0 with the FMI 3.0 data "
                "types read as Real and Integer, against the SSP 1.0 schema " if ssp2
                else "does not conform to the SSP 1.0 schema (")
        raise SetupError(what + f"{schema_file}): " + "; ".join(errors) + ".", file=display)


def _prefixed(message: str) -> str:
    """A schema message with ``{http://ssp-standard.org/SSP1/SystemStructureDescription}Connector``
    written as ``ssd:Connector``, as the standard names elements."""
    for prefix, uri in NS.items():
        message = message.replace(f"{{{uri}}}", f"{prefix}:")
    return message


def as_ssp1(root: etree._Element) -> bool:
    """Read an SSP 2.0 document (or an SSP 2.0 part of a 1.0 one, such as an inline ParameterSet)
    as SSP 1.0, in place, and say whether it was 2.0.  SSP 2.0 keeps the SSP 1.0 namespaces
    (http://ssp-standard.org/SSP1/...) and marks a file's root with ``version="2.0"``; its FMI 3.0
    data types (Float64, Int32, ...) become Real and Integer.  What else 2.0 adds (clocks, arrays,
    new connector kinds, components without a source, MetaData) stays, and `validate_schema`
    refuses it by element and line.  Versioned roots inside ``root`` (inline parameter sets and
    mappings) are left to their own call."""
    ssp2 = root.get("version", "").startswith("2.")
    if not ssp2:
        return False
    root.set("version", "1.0")
    stack = list(root)
    while stack:
        el = stack.pop()
        if not isinstance(el.tag, str):
            continue
        q = etree.QName(el)
        if (q.namespace, q.localname) in VERSIONED_ROOTS:
            continue
        if q.namespace in NS.values() and q.localname in SSP2_TYPES:
            el.tag = etree.QName(q.namespace, SSP2_TYPES[q.localname]).text
        stack.extend(el)
    return True


# --------------------------------------------------------------------------- SSD

def _read_ssd(path: Path, display: str | None = None) -> RawStructure:
    display = display or str(path)
    tree = parse_xml(path, display)
    root = tree.getroot()
    if etree.QName(root).namespace != NS["ssd"] or etree.QName(root).localname != "SystemStructureDescription":
        raise SetupError("the root element is not an SSP ssd:SystemStructureDescription "
                         f"(found {root.tag}).", file=display, element=f"line {root.sourceline}")
    validate_schema(tree, "SystemStructureDescription.xsd", display, ssp2=as_ssp1(root))

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
                    connections=[], parameters=_read_bindings(system, base_dir, display, None)[0])
    elements = system.find("ssd:Elements", NS)
    for el in (elements if elements is not None else []):
        if not isinstance(el.tag, str):
            continue
        local = etree.QName(el).localname
        element_name = el.get("name")
        if element_name in raw.components or element_name in raw.systems or element_name in raw.references:
            raise SetupError(f"two elements of system '{name}' are named '{element_name}'.", file=display,
                             element=f"ssd:{local} (line {el.sourceline})")
        if local == "SignalDictionaryReference":
            raw.references[element_name] = _read_reference(el, display)
            continue
        if local == "System":
            raw.systems[element_name] = _read_system(el, base_dir, display)
        else:
            raw.components[element_name] = _read_component(el, base_dir, display)
        raw.elements.append(element_name)
    for d in system.iterfind("ssd:SignalDictionaries/ssd:SignalDictionary", NS):
        dictionary = _read_dictionary(d, base_dir, display)
        if dictionary.name in raw.dictionaries:
            raise SetupError(f"two signal dictionaries of system '{name}' are named '{dictionary.name}'.",
                             file=display, element=f"ssd:SignalDictionary (line {d.sourceline})")
        raw.dictionaries[dictionary.name] = dictionary
    raw.connections = [_read_connection(c, display) for c in system.iterfind("ssd:Connections/ssd:Connection", NS)]
    return raw


def _read_reference(el: etree._Element, display: str) -> SignalReference:
    name = el.get("name")
    ref = SignalReference(name, el.get("dictionary"), el.sourceline, {})
    for c in el.iterfind("ssd:Connectors/ssd:Connector", NS):
        conn = _read_connector(c)
        if conn.name in ref.connectors:
            raise SetupError(f"connector '{conn.name}' is declared twice.", file=display,
                             element=f"ssd:SignalDictionaryReference '{name}' (line {el.sourceline})")
        ref.connectors[conn.name] = conn
    return ref


def _read_dictionary(el: etree._Element, base_dir: Path, display: str) -> SignalDictionary:
    """An ``ssd:SignalDictionary``: its entries from the ``.ssb`` source or the inline ``ssb:SignalDictionary``."""
    name = el.get("name")
    where = f"ssd:SignalDictionary '{name}' (line {el.sourceline})"
    dtype = el.get("type", SIGNAL_DICTIONARY_MIME)
    if dtype != SIGNAL_DICTIONARY_MIME:
        raise SetupError(f"signal dictionary type '{dtype}' is not supported (only {SIGNAL_DICTIONARY_MIME}).",
                         file=display, element=where)
    source = el.get("source")
    if source is not None:
        path = _source_file(source, base_dir, display, where, "signal dictionary")
        file, root = str(path), _read_document(path, "ssb", "SignalDictionary", "SystemStructureSignalDictionary.xsd")
    else:
        file, root = display, el.find("ssb:SignalDictionary", NS)
        if root is None:
            raise SetupError("a signal dictionary needs a source (.ssb) or an inline ssb:SignalDictionary.",
                             file=display, element=where)
        validate_schema(root, "SystemStructureSignalDictionary.xsd", display, ssp2=as_ssp1(root))
    units = root.find("ssb:Units", NS)
    if units is not None and any(isinstance(u.tag, str) for u in units):
        raise SetupError("units declared in a signal dictionary are not supported; declare them in the SSD's "
                         "ssd:Units (the master converts dictionary signals with the SSD's units).", file=file,
                         element=f"ssb:Units (line {units.sourceline})")
    entries: dict[str, Connector] = {}
    for entry in root.iterfind("ssb:DictionaryEntry", NS):
        conn = replace(_read_connector(entry), kind="signal")
        if conn.name in entries:
            raise SetupError(f"dictionary entry '{conn.name}' is declared twice.", file=file,
                             element=f"ssb:DictionaryEntry (line {entry.sourceline})", variable=conn.name)
        entries[conn.name] = conn
    return SignalDictionary(name, el.sourceline, file, entries)


def _read_component(el: etree._Element, base_dir: Path, display: str) -> Component:
    name = el.get("name")
    where = f"ssd:Component '{name}' (line {el.sourceline})"
    ctype = el.get("type", FMU_MIME)
    if ctype != FMU_MIME:
        raise SetupError(f"component type '{ctype}' is not supported; only FMUs ({FMU_MIME}).",
                         file=display, element=where)
    connectors: dict[str, Connector] = {}
    for c in el.iterfind("ssd:Connectors/ssd:Connector", NS):
        conn = _read_connector(c)
        if conn.name in connectors:
            raise SetupError(f"connector '{conn.name}' is declared twice.", file=display, element=where)
        connectors[conn.name] = conn
    parameters, bindings = _read_bindings(el, base_dir, display, el.get("source"))
    return Component(name=name, source=el.get("source"), line=el.sourceline, connectors=connectors,
                     parameters=parameters, implementation=el.get("implementation", "any"),
                     solver=_read_solver_annotation(el, display), component_bindings=bindings)


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
    suppress = c.get("suppressUnitConversion", "false") in ("true", "1")
    # an empty element name is the enclosing system, as an omitted one (OMSimulator writes
    # startElement="" for a system's own connector; the schema's xs:string accepts it)
    return Connection(c.get("startElement") or None, c.get("startConnector"), c.get("endElement") or None,
                      c.get("endConnector"), _read_transformation(c, display), suppress, c.sourceline)


def _read_transformation(el: etree._Element, display: str) -> Affine | MappingTable | None:
    """An ``ssd:Connection``'s transformation (the schema allows one, GTransformationChoice): its
    ``ssc:LinearTransformation`` or mapping table, as read (`cosim.model.transforms`)."""
    linear = el.find("ssc:LinearTransformation", NS)
    if linear is not None:
        return Affine(_float_attr(linear, "factor", display, default=1.0),
                      _float_attr(linear, "offset", display, default=0.0))
    for local, (kind, parse) in _TABLES.items():
        table_el = el.find(f"ssc:{local}", NS)
        if table_el is not None:
            return MappingTable(kind, tuple(_read_table(table_el, parse, display).items()), table_el.sourceline)
    return None


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


def _read_bindings(owner: etree._Element, base_dir: Path, display: str,
                   fmu_source: str | None) -> tuple[list[ParameterValue], tuple[ComponentBinding, ...]]:
    """The parameter values of ``owner``'s bindings, and its ``sourceBase="component"`` ones,
    whose source is inside the component's FMU ``fmu_source`` (None for a system, which has
    none), to read once the FMU is located (`read_component_bindings`)."""
    values: list[ParameterValue] = []
    pending: list[ComponentBinding] = []
    for binding in owner.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
        where = f"ssd:ParameterBinding (line {binding.sourceline})"
        btype = binding.get("type", PARAMETER_SET_MIME)
        if btype != PARAMETER_SET_MIME:
            raise SetupError(f"parameter binding type '{btype}' is not supported.", file=display, element=where)
        prefix = binding.get("prefix", "")
        source = binding.get("source")
        base = binding.get("sourceBase", "SSD")
        if base not in ("SSD", "component"):
            raise SetupError(f"sourceBase='{base}' is not 'SSD' or 'component'.", file=display, element=where)
        mapping = binding.find("ssd:ParameterMapping", NS)
        entries = None if mapping is None else _read_mapping(mapping, base_dir, display)
        if base == "component":
            if fmu_source is None or source is None:
                raise SetupError("sourceBase='component' needs a source and a component (SSP 1.0: the source is "
                                 "relative to the component's FMU).", file=display, element=where)
            pending.append(ComponentBinding(source, prefix, None if entries is None else tuple(entries), len(values),
                                            display, where))
            continue
        if source is not None:
            parsed = read_ssv(_source_file(source, base_dir, display, where, "parameter set"))
        else:
            inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            if inline is None:
                raise SetupError("a parameter binding needs a source or inline ssd:ParameterValues.",
                                 file=display, element=where)
            # the SSD schema lets ssd:ParameterValues hold anything: check the inline set as an .ssv is
            validate_schema(inline, "SystemStructureParameterValues.xsd", display, ssp2=as_ssp1(inline))
            parsed = _read_parameter_set(inline, display)
        values.extend(_bound(parsed, prefix, entries))
    return values, tuple(pending)


def _bound(parsed: list[ParameterValue], prefix: str, entries) -> list[ParameterValue]:
    """A binding's values: SSP 1.0 ParameterBinding ``prefix`` prepended to the names of the
    source, then its mapping (`cosim.read.mapping.apply_mapping`), if it has one."""
    named = [replace(p, name=prefix + p.name) for p in parsed]
    return named if entries is None else apply_mapping(named, list(entries))


def read_component_bindings(structure: SystemStructure, fmu_paths: dict[str, Path]) -> None:
    """Read, in place, the ``sourceBase="component"`` bindings of each component from the FMU
    located for it (`cosim.model.structure.ComponentBinding`), wherever it was found."""
    for name, comp in structure.components.items():
        values = list(comp.parameters)
        for b in reversed(comp.component_bindings):
            parsed = _read_ssv_in_fmu(b.source, fmu_paths[name], b.display, b.where)
            values[b.position:b.position] = _bound(parsed, b.prefix, b.mapping)
        structure.components[name] = replace(comp, parameters=values, component_bindings=())


def _check_source_base(el: etree._Element, display: str, where: str, kind: str) -> None:
    if el.get("sourceBase", "SSD") != "SSD":
        raise SetupError(f"sourceBase='component' is not supported; give the {kind} relative to the SSD.",
                         file=display, element=where)


def _source_file(source: str, base_dir: Path, display: str, where: str, what: str) -> Path:
    """The file a ``source`` URI names, resolved and confined as every SSP resource (`resolve_uri`)."""
    try:
        path = resolve_uri(source, base_dir)
    except SetupError as e:
        raise SetupError(e.detail, file=display, element=where) from None
    if not is_file(path):
        raise SetupError(f"{what} '{source}' not found (looked at {path}).", file=display, element=where)
    return path


def _read_mapping(el: etree._Element, base_dir: Path, display: str) -> list[MappingEntry]:
    """The entries of an ``ssd:ParameterMapping``: from its ``.ssm`` source or inline."""
    where = f"ssd:ParameterMapping (line {el.sourceline})"
    mtype = el.get("type", PARAMETER_MAPPING_MIME)
    if mtype != PARAMETER_MAPPING_MIME:
        raise SetupError(f"parameter mapping type '{mtype}' is not supported (only {PARAMETER_MAPPING_MIME}).",
                         file=display, element=where)
    _check_source_base(el, display, where, ".ssm")
    source = el.get("source")
    children = [c for c in el if isinstance(c.tag, str)]
    if source is not None:
        if children:
            raise SetupError("a parameter mapping with a source must be empty (SSP 1.0 ParameterMapping).",
                             file=display, element=where)
        return read_ssm(_source_file(source, base_dir, display, where, "parameter mapping"))
    inline = el.find("ssm:ParameterMapping", NS)
    if inline is None or len(children) != 1:
        raise SetupError("a parameter mapping needs a source (.ssm) or one inline ssm:ParameterMapping.",
                         file=display, element=where)
    validate_schema(inline, "SystemStructureParameterMapping.xsd", display, ssp2=as_ssp1(inline))
    return _read_mapping_entries(inline, display)


def read_ssm(path: str | Path) -> list[MappingEntry]:
    """Read an ``.ssm`` parameter mapping file (SystemStructureParameterMapping.xsd)."""
    root = _read_document(path, "ssm", "ParameterMapping", "SystemStructureParameterMapping.xsd")
    return _read_mapping_entries(root, str(path))


#: the transformations of a mapping entry (SSP 1.0 GTransformationChoice) and how a MapEntry value reads
_TABLES = {"BooleanMappingTransformation": ("Boolean", lambda text: text.strip() in ("true", "1")),
           "IntegerMappingTransformation": ("Integer", int),
           "EnumerationMappingTransformation": ("Enumeration", str)}


def _read_mapping_entries(mapping: etree._Element, display: str) -> list[MappingEntry]:
    entries: list[MappingEntry] = []
    targets: dict[str, int] = {}
    for e in mapping.iterfind("ssm:MappingEntry", NS):
        if e.get("source") == "":  # OMSimulator's mapping templates: a target awaiting its source maps nothing
            continue
        target = e.get("target")
        if target in targets:
            raise SetupError(f"two mapping entries map to '{target}' (lines {targets[target]} and {e.sourceline}); "
                             "SSP 1.0 forbids mapping several parameters to one name.", file=display,
                             element=f"ssm:MappingEntry (line {e.sourceline})", variable=target)
        targets[target] = e.sourceline
        entry = MappingEntry(e.get("source"), target, e.get("suppressUnitConversion", "false") in ("true", "1"),
                             display, e.sourceline)
        transform = _read_transformation(e, display)
        if isinstance(transform, MappingTable):  # a table of ssv values (item names for an Enumeration)
            entry = replace(entry, kind=transform.kind, transform=Table(FrozenMap(transform.entries),
                                                                        element=transform.element))
        elif transform is not None:
            entry = replace(entry, kind="Linear", transform=transform)
        entries.append(entry)
    return entries


def _read_table(el: etree._Element, parse, display: str) -> dict:
    """The ``ssc:MapEntry`` source → target table of a mapping transformation; a source given twice
    is refused (SSP 1.0: entries MUST be unambiguous)."""
    table: dict = {}
    for entry in el.iterfind("ssc:MapEntry", NS):
        source, target = parse(entry.get("source")), parse(entry.get("target"))
        if source in table:
            raise SetupError(f"source value '{entry.get('source')}' is mapped twice; SSP 1.0 mapping "
                             "transformations must be unambiguous.", file=display,
                             element=f"ssc:MapEntry (line {entry.sourceline})")
        table[source] = target
    return table


def read_ssv(path: str | Path) -> list[ParameterValue]:
    """Read an ``.ssv`` parameter set file (SystemStructureParameterValues.xsd), SSP 1.0 or 2.0 (`as_ssp1`)."""
    root = _read_document(path, "ssv", "ParameterSet", "SystemStructureParameterValues.xsd")
    return _read_parameter_set(root, str(path))


def _read_ssv_in_fmu(name: str, fmu: Path, display: str, where: str) -> list[ParameterValue]:
    """The ``.ssv`` a ``sourceBase="component"`` binding names: the file ``name`` inside the
    component's FMU archive (SSP 1.0 §5.3.3 ParameterBinding, e.g. ``resources/params.ssv``),
    never a path outside it (`cosim.safeio.read_member`)."""
    inner = f"{fmu}!/{name}"
    tree = parse_xml_bytes(read_member(fmu, unquote(name), display, where), inner)
    root = _check_root(tree, inner, "ssv", "ParameterSet", "SystemStructureParameterValues.xsd")
    return _read_parameter_set(root, inner)


def _read_document(path: str | Path, prefix: str, localname: str, schema: str) -> etree._Element:
    """The root element of an SSP file (``.ssv``, ``.ssm``, ``.ssb``), parsed as untrusted XML
    (`_check_root`)."""
    return _check_root(parse_xml(Path(path)), str(path), prefix, localname, schema)


def _check_root(tree: etree._ElementTree, display: str, prefix: str, localname: str, schema: str) -> etree._Element:
    """The root of ``tree``, checked to be ``prefix:localname`` and validated against ``schema``
    (SSP 1.0, or 2.0 read as 1.0: `as_ssp1`)."""
    root = tree.getroot()
    if etree.QName(root).namespace != NS[prefix] or etree.QName(root).localname != localname:
        raise SetupError(f"the root element is not an SSP {prefix}:{localname} (found {root.tag}).",
                         file=display, element=f"line {root.sourceline}")
    validate_schema(tree, schema, display, ssp2=as_ssp1(root))
    return root


def _read_parameter_set(pset: etree._Element, display: str) -> list[ParameterValue]:
    values = []
    units = read_units(pset.find("ssv:Units", NS), display)
    for p in pset.iterfind("ssv:Parameters/ssv:Parameter", NS):
        where = {"file": display, "element": f"ssv:Parameter (line {p.sourceline})", "variable": p.get("name")}
        v = next((t for t in p if isinstance(t.tag, str) and etree.QName(t).localname in VALUE_TYPES), None)
        if v is None:
            raise SetupError(f"the parameter has no value element (one of {', '.join(VALUE_TYPES)}).", **where)
        kind = etree.QName(v).localname
        text = v.get("value")
        if kind in ("Real", "Integer"):
            # an inline ssv:ParameterSet of an SSD is not held to the SSV schema's xs:double / xs:int
            try:
                value: float | int | bool | str = float(text) if kind == "Real" else int(text)
            except (TypeError, ValueError):
                raise SetupError(f"ssv:{kind} value {text!r} is not a number.", **where) from None
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

