"""The SSP reader and the CLI under malformed input: every rejection is one clear SetupError.

Random documents are mutations of the real scenarios' SystemStructure.ssd and .ssv
files (elements deleted, duplicated, renamed or moved; attributes deleted or given bad
numbers and random text; wrong namespaces; truncation; control characters; deep
nesting; huge values; wrong encoding declarations; byte order marks; entity
declarations) and of ``.ssp`` archives built from them (random bytes, truncation,
flipped bytes, traversal and duplicate member names, other compression methods,
encrypted or symbolic-link members).  Properties: `cosim.read.ssp.load` and
`cosim.read.ssp.read_ssv` raise nothing but `SetupError`, whose message names the file;
each example ends within the Hypothesis deadline (5 s); ``cosim validate`` exits 2
with one message and no traceback.

Example counts scale with the Hypothesis profile (tests/conftest.py): 500 in all with
the default profile, 10 000 with ``COSIM_FUZZ=nightly`` (or ``--hypothesis-profile
nightly``).  The explicit tests at the end cover the attacks a random search would
rarely build: billion laughs, external entities, zip bombs, lying sizes, traversal.
"""
from __future__ import annotations

import copy
import shutil
import io
import stat
import struct
import tempfile
import warnings
import zipfile
import zlib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from lxml import etree

import cosim.read.resources
from cosim import safeio
from cosim.read import ssp
from cosim.cli import main
from cosim.errors import SetupError

SCENARIOS = sorted(p.parent for p in Path(__file__).resolve().parents[2].glob("ssp/*/SystemStructure.ssd"))
SSD_SOURCES = {s.name: (s / "SystemStructure.ssd").read_bytes() for s in SCENARIOS}
SSV_SOURCES = {f"{s.name}/{f.name}": f.read_bytes() for s in SCENARIOS for f in sorted(s.glob("*.ssv"))}
SSP_NAMES = ["SystemStructureDescription", "System", "Elements", "Component", "Connectors", "Connector",
             "Connections", "Connection", "ParameterBindings", "ParameterBinding", "ParameterValues",
             "ParameterSet", "Parameters", "Parameter", "Real", "Integer", "Boolean", "String",
             "DefaultExperiment", "Annotations", "Annotation", "LinearTransformation", "Units", "Unit",
             "BaseUnit", "SignalDictionaries", "ParameterMapping", "Enumerations"]
BAD_VALUES = ["nan", "NaN", "inf", "-INF", "1e999", "-1e999", "", " ", "abc", "0x10", "1,5", "1e", "--1",
              "true", "2147483648", "-0", "\u0661\u0662", "resources/../../x.fmu", "file:///etc/passwd",
              "http://[::1", "%00", "a.b.c", "../", "ModelExchange", "CoSimulation", "input", "output"]
NAMESPACES = [*ssp.NS.values(), "", "urn:wrong", "http://ssp-standard.org/SSP2/SystemStructureDescription"]
BOMS = [b"\xef\xbb\xbf", b"\xff\xfe", b"\xfe\xff", b"\x00\x00\xfe\xff"]
ENCODINGS = ["UTF-16", "UTF-32", "ISO-8859-1", "ascii", "bogus", "EBCDIC-US", "UTF-7", ""]
XML_TEXT = st.text(st.characters(blacklist_categories=("Cs", "Cc")), max_size=40)


def _scaled(share: float) -> int:
    """This test's share of the profile's examples (shares sum to 5: 500 default, 10 000 nightly)."""
    return max(1, int(share * settings.default.max_examples))


FUZZ = {"suppress_health_check": [HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                  HealthCheck.data_too_large, HealthCheck.large_base_example]}


# --------------------------------------------------------------------------- strategies

@st.composite
def _tree_mutation(draw, root: etree._Element) -> None:
    """One structural change to the parsed document, in place."""
    elements = [e for e in root.iter() if isinstance(e.tag, str)]
    el = draw(st.sampled_from(elements))
    op = draw(st.sampled_from(["delete", "duplicate", "rename", "namespace", "drop_attr", "bad_attr",
                               "add_attr", "nest", "huge", "move", "text", "reuse", "reuse"]))
    parent = el.getparent()
    if op == "reuse" and el.attrib:    # a value from elsewhere in the document: valid XML, wrong meaning
        values = sorted({v for e in elements for v in e.attrib.values()})
        el.set(draw(st.sampled_from(sorted(el.attrib))), draw(st.sampled_from(values)))
    elif op == "delete" and parent is not None:
        parent.remove(el)
    elif op == "duplicate" and parent is not None:
        parent.insert(parent.index(el), copy.deepcopy(el))
    elif op == "rename":
        el.tag = etree.QName(etree.QName(el).namespace, draw(st.sampled_from(SSP_NAMES))).text
    elif op == "namespace":
        ns = draw(st.sampled_from(NAMESPACES))
        el.tag = etree.QName(ns or None, etree.QName(el).localname).text
    elif op == "drop_attr" and el.attrib:
        del el.attrib[draw(st.sampled_from(sorted(el.attrib)))]
    elif op == "bad_attr" and el.attrib:
        el.set(draw(st.sampled_from(sorted(el.attrib))), draw(st.sampled_from(BAD_VALUES) | XML_TEXT))
    elif op == "add_attr":
        name = draw(st.sampled_from(["name", "value", "unit", "kind", "source", "factor", "offset",
                                     "implementation", "type", "startTime", "stopTime", "stepSize",
                                     "suppressUnitConversion", "prefix", "sourceBase", "version"]))
        el.set(name, draw(st.sampled_from(BAD_VALUES) | XML_TEXT))
    elif op == "nest" and parent is not None:
        depth = draw(st.sampled_from([2, 50, 300]))
        outer = inner = etree.Element(el.tag)
        for _ in range(depth - 1):
            inner = etree.SubElement(inner, el.tag)
        parent.replace(el, outer)
        inner.append(el)
    elif op == "huge":
        el.set(draw(st.sampled_from(["name", "value", "source"])), "x" * draw(st.sampled_from([10**3, 10**5, 10**6])))
    elif op == "move" and parent is not None:
        target = draw(st.sampled_from(elements))
        if el not in list(target.iterancestors()) and target is not el:
            target.append(el)
    elif op == "text":
        el.text = draw(XML_TEXT)


@st.composite
def _byte_mutation(draw, data: bytes) -> bytes:
    """One change to the serialized bytes: what an editor, a transfer or an attacker does."""
    op = draw(st.sampled_from(["truncate", "insert", "control", "flip", "encoding", "bom", "utf16",
                               "entities"]))
    at = draw(st.integers(0, len(data)))
    if op == "truncate":
        return data[:at]
    if op == "insert":
        return data[:at] + draw(st.text(max_size=20)).encode("utf-8", "surrogatepass") + data[at:]
    if op == "control":
        return data[:at] + draw(st.binary(min_size=1, max_size=8)) + data[at:]
    if op == "flip" and data:
        at = min(at, len(data) - 1)
        return data[:at] + bytes([data[at] ^ draw(st.integers(1, 255))]) + data[at + 1:]
    if op == "encoding":
        enc = draw(st.sampled_from(ENCODINGS)).encode()
        body = data.split(b"?>", 1)[-1] if data.startswith(b"<?xml") else data
        return b'<?xml version="1.0" encoding="' + enc + b'"?>' + body
    if op == "bom":
        return draw(st.sampled_from(BOMS)) + data
    if op == "utf16":
        return data.decode("utf-8", "replace").encode(draw(st.sampled_from(["utf-16", "utf-16-le", "utf-32"])))
    if op == "entities":
        decl = draw(st.sampled_from([
            '<!DOCTYPE x [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>',
            '<!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]>',
            '<!DOCTYPE x [<!ENTITY % p SYSTEM "file:///etc/passwd"> %p;]>',
            '<!DOCTYPE x SYSTEM "http://127.0.0.1:9/x.dtd">',
            '<!DOCTYPE x>']))
        head, sep, body = data.partition(b"?>")
        return head + sep + decl.encode() + body if sep else decl.encode() + data
    return data


@st.composite
def malformed_xml(draw, kind: str, key: str | None = None, byte_level: bool = True) -> tuple[str, bytes]:
    """A real document (``kind`` "ssd" or "ssv") with tree-level and then byte-level mutations;
    at least one mutation in all.  Without ``byte_level`` the document stays well formed, so
    the mutations reach the checks after parsing (schema, flattening, units, the FMUs)."""
    sources = SSD_SOURCES if kind == "ssd" else SSV_SOURCES
    key = key or draw(st.sampled_from(sorted(sources)))
    root = etree.fromstring(sources[key], etree.XMLParser(remove_comments=True))
    tree_mutations = draw(st.integers(0 if byte_level else 1, 3))
    for _ in range(tree_mutations):
        draw(_tree_mutation(root))
    data = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    for _ in range(draw(st.sampled_from([0, 0, 1, 2] if tree_mutations else [1, 2])) if byte_level else 0):
        data = draw(_byte_mutation(data))
    return key, data


NASTY_MEMBERS = ["../evil.txt", "a/../../evil.txt", "/etc/evil", "C:/evil", "C:evil", "..\\evil.txt",
                 "\\\\host\\share\\x", "", "/", "SystemStructure.ssd", "resources/", "resources/../x",
                 "ü/ñ.ssv", "a" * 300, "a//b", "./SystemStructure.ssd", "x\x00y"]


def _tiny_fmu() -> bytes:
    """A zip holding only a modelDescription.xml: enough for the archive checks."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", '<fmiModelDescription fmiVersion="2.0"/>')
    return buffer.getvalue()


@st.composite
def malformed_archive(draw) -> bytes:
    """Random bytes, or a scenario packed as .ssp and then damaged."""
    if draw(st.integers(0, 9)) == 0:
        prefix = draw(st.sampled_from([b"", b"PK\x03\x04", b"PK\x05\x06"]))
        return prefix + draw(st.binary(max_size=300))
    key = draw(st.sampled_from(sorted(SSD_SOURCES)))
    ssd = draw(malformed_xml("ssd", key))[1] if draw(st.booleans()) else SSD_SOURCES[key]
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as z:
        if draw(st.integers(0, 9)) > 0:
            z.writestr("SystemStructure.ssd", ssd)
        for name, data in SSV_SOURCES.items():
            if name.startswith(key + "/"):
                z.writestr(name.split("/", 1)[1], data)
        if draw(st.integers(0, 4)) == 0:     # a damaged FMU: opened later by fmpy, checked now
            fmu = draw(st.sampled_from([b"", b"PK\x03\x04", _tiny_fmu()[:-22], _tiny_fmu()]))
            z.writestr(f"resources/{draw(st.sampled_from(['PID.fmu', 'X.FMU', 'a/b.fmu']))}",
                       fmu + draw(st.binary(max_size=16)))
        for _ in range(draw(st.integers(0, 2))):
            info = zipfile.ZipInfo(draw(st.sampled_from(NASTY_MEMBERS) | st.text(min_size=1, max_size=30)))
            info.compress_type = draw(st.sampled_from([zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED,
                                                       zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA]))
            if draw(st.integers(0, 5)) == 0:
                info.external_attr = (stat.S_IFLNK | 0o777) << 16
            if draw(st.integers(0, 5)) == 0:
                info.flag_bits |= 0x1
            z.writestr(info, draw(st.binary(max_size=64)))
    data = buffer.getvalue()
    for _ in range(draw(st.integers(0, 2))):
        op = draw(st.sampled_from(["truncate", "flip", "chop_head"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if op == "truncate":
            data = data[:at]
        elif op == "flip" and data:
            data = data[:at] + bytes([data[at] ^ draw(st.integers(1, 255))]) + data[at + 1:]
        elif op == "chop_head":
            data = data[at:]
    return data


# --------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    """Each scenario's parameter sets copied to a folder of its own, where fuzzed SSDs are written."""
    root = tmp_path_factory.mktemp("fuzz")
    for scenario in SCENARIOS:
        (root / scenario.name).mkdir()
        for ssv in scenario.glob("*.ssv"):
            (root / scenario.name / ssv.name).write_bytes(ssv.read_bytes())
    return root


def _assert_names_file(error: SetupError, file: Path) -> None:
    event(" ".join(error.detail.split()[:4]))     # what was refused: --hypothesis-show-statistics
    text = str(error)
    assert error.file and error.file in text and str(file.parent) in error.file, text


def _load_only_setup_errors(path: Path) -> None:
    try:
        ssp.load(path).close()
        event("accepted")
    except SetupError as e:
        _assert_names_file(e, path)


# --------------------------------------------------------------------------- properties

@settings(max_examples=_scaled(2.0), **FUZZ)
@given(doc=malformed_xml("ssd"))
def test_malformed_ssd_gives_setup_error(workspace, doc):
    scenario, data = doc
    path = workspace / scenario / "fuzz.ssd"
    path.write_bytes(data)
    _load_only_setup_errors(path)


@settings(max_examples=_scaled(1.0), **FUZZ)
@given(doc=malformed_xml("ssv"))
def test_malformed_ssv_gives_setup_error(workspace, doc):
    _, data = doc
    path = workspace / "fuzz.ssv"
    path.write_bytes(data)
    try:
        ssp.read_ssv(path)
    except SetupError as e:
        _assert_names_file(e, path)


@pytest.mark.filterwarnings("ignore:Duplicate name:UserWarning")  # duplicate members are one of the malformations
@settings(max_examples=_scaled(1.2), **FUZZ)
@given(data=malformed_archive())
def test_malformed_archive_gives_setup_error(workspace, data):
    path = workspace / "fuzz.ssp"
    path.write_bytes(data)
    _load_only_setup_errors(path)


@pytest.fixture
def fmus_in_resources(workspace, built_fmus, monkeypatch) -> Path:
    """Our FMUs (built once per session) as every workspace scenario's resources/ folder.

    The FMU providers are switched off for these tests: a fuzzed source name must not
    make the greyfmu provider build an FMU in the middle of an example.
    """
    fmu_dir = next(iter(built_fmus.values())).parent
    for scenario in SCENARIOS:
        link = workspace / scenario.name / "resources"
        if not link.exists():
            link.symlink_to(fmu_dir, target_is_directory=True)
    monkeypatch.setattr(cosim.read.resources, "providers", lambda: ([], []))
    return workspace


@settings(max_examples=_scaled(0.8), **FUZZ)
@given(doc=malformed_xml("ssd", byte_level=False))
def test_cli_validate_exits_2_without_traceback(fmus_in_resources, capsys, doc):
    scenario, data = doc
    path = fmus_in_resources / scenario / "fuzz.ssd"
    path.write_bytes(data)
    code = main(["validate", str(path)])
    captured = capsys.readouterr()
    assert code in (0, 2), captured.err
    event("valid" if code == 0 else " ".join(captured.err.split(": ")[-1].split()[:4]))
    if code == 2:
        assert captured.err.startswith("cosim: error: ") and "\n\n" not in captured.err.strip(), captured.err
        assert "Traceback" not in captured.err and str(fmus_in_resources) in captured.err, captured.err


# --------------------------------------------------------------------------- explicit attacks

SSD_HEAD = '<?xml version="1.0" encoding="UTF-8"?>\n'
MINIMAL_SSD = (f'<ssd:SystemStructureDescription xmlns:ssd="{ssp.NS["ssd"]}" version="1.0" name="x">'
               '<ssd:System name="s"/></ssd:SystemStructureDescription>')
BILLION_LAUGHS = ('<!DOCTYPE lolz [<!ENTITY lol "lol">'
                  + "".join(f'<!ENTITY lol{i} "{("&lol" + (str(i - 1) if i > 1 else "") + ";") * 10}">'
                            for i in range(1, 10))
                  + "]>\n")


def _refused(call, *args, **kwargs) -> str:
    with pytest.raises(SetupError) as info:
        call(*args, **kwargs)
    return str(info.value)


def test_billion_laughs_ssd_is_refused(tmp_path):
    path = tmp_path / "laughs.ssd"
    path.write_text(SSD_HEAD + BILLION_LAUGHS + MINIMAL_SSD.replace('name="x"', 'name="&lol9;"'))
    message = _refused(ssp.load, path)
    assert str(path) in message and "entity declarations are not allowed" in message


def test_billion_laughs_below_the_parser_limit_is_still_refused(tmp_path):
    """Few enough expansions for libxml2 to accept: the declaration itself is refused."""
    path = tmp_path / "few.ssd"
    path.write_text(SSD_HEAD + '<!DOCTYPE x [<!ENTITY a "aa"><!ENTITY b "&a;&a;">]>\n'
                    + MINIMAL_SSD.replace('name="x"', 'name="&b;"'))
    message = _refused(ssp.load, path)
    assert "entity declarations are not allowed" in message and "a, b" in message


def test_external_entity_ssd_does_not_read_the_file(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOP-SECRET-CONTENT")
    path = tmp_path / "xxe.ssd"
    path.write_text(SSD_HEAD + f'<!DOCTYPE x [<!ENTITY e SYSTEM "{secret.as_uri()}">]>\n'
                    + MINIMAL_SSD.replace('name="x"', 'name="&e;"'))
    message = _refused(ssp.load, path)
    assert str(path) in message and "entity declarations are not allowed" in message
    assert "TOP-SECRET" not in message
    passwd = tmp_path / "passwd.ssd"
    passwd.write_text(SSD_HEAD + '<!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]>\n'
                      + MINIMAL_SSD.replace("<ssd:System", "<ssd:System description='&e;'"))
    assert "entity declarations are not allowed" in _refused(ssp.load, passwd)


def test_external_dtd_is_refused(tmp_path):
    path = tmp_path / "dtd.ssd"
    path.write_text(SSD_HEAD + '<!DOCTYPE x SYSTEM "http://127.0.0.1:9/x.dtd">\n' + MINIMAL_SSD)
    message = _refused(ssp.load, path)
    assert str(path) in message and "external DTD" in message


def test_ssv_with_parameter_entities_is_refused(tmp_path):
    path = tmp_path / "p.ssv"
    path.write_text(SSD_HEAD + '<!DOCTYPE x [<!ENTITY % p "<!ENTITY v \'1.0\'>"> %p;]>\n'
                    f'<ssv:ParameterSet xmlns:ssv="{ssp.NS["ssv"]}" version="1.0" name="p"><ssv:Parameters>'
                    '<ssv:Parameter name="k"><ssv:Real value="&v;"/></ssv:Parameter>'
                    '</ssv:Parameters></ssv:ParameterSet>')
    message = _refused(ssp.read_ssv, path)
    assert str(path) in message and "entity declarations are not allowed" in message


def _scenario_archive(path: Path, extra: dict[str, bytes] | None = None) -> Path:
    """pid_fopdt's SSD and parameter sets packed as an .ssp, plus ``extra`` members."""
    scenario = Path("ssp/pid_fopdt")
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(scenario / "SystemStructure.ssd", "SystemStructure.ssd")
        for ssv in scenario.glob("*.ssv"):
            z.write(ssv, ssv.name)
        for name, data in (extra or {}).items():
            z.writestr(name, data)
    return path


def _deflate(data: bytes) -> bytes:
    packer = zlib.compressobj(6, zlib.DEFLATED, -15)
    return packer.compress(data) + packer.flush()


def _scenario_members() -> list[tuple[str, bytes, int, int]]:
    """pid_fopdt's SSD and parameter sets as raw members: (name, deflated, size, CRC-32)."""
    scenario = Path("ssp/pid_fopdt")
    files = [scenario / "SystemStructure.ssd", *sorted(scenario.glob("*.ssv"))]
    return [(f.name, _deflate(f.read_bytes()), f.stat().st_size, zlib.crc32(f.read_bytes())) for f in files]


def _raw_zip(path: Path, members: list[tuple[str, bytes, int, int]]) -> Path:
    """A ZIP written field by field (APPNOTE.TXT 4.3.7 local header, 4.3.12 central directory,
    4.3.16 end record), so a member's header can declare any size: how bombs and liars are made."""
    out = io.BytesIO()
    offsets = []
    for name, raw, size, crc in members:
        offsets.append(out.tell())
        out.write(struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0, crc, len(raw), size,
                              len(name.encode()), 0) + name.encode() + raw)
    directory = out.tell()
    for (name, raw, size, crc), offset in zip(members, offsets):
        out.write(struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 8, 0, 0, crc, len(raw), size,
                              len(name.encode()), 0, 0, 0, 0, 0, offset) + name.encode())
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(members), len(members), out.tell() - directory,
                      directory, 0)
    path.write_bytes(out.getvalue() + end)
    return path


def _zeros_bomb(gib: int) -> tuple[bytes, int, int]:
    """``gib`` GiB of zeros as one deflate stream (1 MiB blocks ending in a full flush repeat
    byte for byte), its size and CRC-32; a few MB, made in about a second."""
    zeros = bytes(1024**2)
    packer = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = packer.compress(zeros) + packer.flush(zlib.Z_FULL_FLUSH)
    crc = 0
    for _ in range(gib * 1024):
        crc = zlib.crc32(zeros, crc)
    return block * (gib * 1024) + packer.flush(), gib * 1024**3, crc


def test_zeros_bomb_helper_makes_a_valid_stream():
    zeros = bytes(1024**2)
    packer = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = packer.compress(zeros) + packer.flush(zlib.Z_FULL_FLUSH)
    assert zlib.decompress(block * 3 + packer.flush(), -15) == bytes(3 * 1024**2)


def test_zip_bomb_is_refused_before_extraction(tmp_path):
    raw, size, crc = _zeros_bomb(3)
    archive = _raw_zip(tmp_path / "bomb.ssp", _scenario_members() + [("resources/zeros.bin", raw, size, crc)])
    assert archive.stat().st_size < 10 * 1024**2
    for limit in (None, 16 * 1024**3):     # the default, and a limit the bomb fits in: the ratio refuses it
        message = _refused(ssp.load, archive, max_unpacked_bytes=limit)
        assert str(archive) in message and "'resources/zeros.bin'" in message and "zip bomb" in message
        assert f"limit {safeio.MAX_COMPRESSION_RATIO}:1" in message


def test_archive_over_the_size_limit_names_member_and_limit(tmp_path, monkeypatch, capsys):
    import random
    table = random.Random(1).randbytes(2 * 1024**2)      # incompressible: only the size limit can refuse it
    archive = _scenario_archive(tmp_path / "big.ssp", {"resources/table.bin": table})
    message = _refused(ssp.load, archive, max_unpacked_bytes=1024**2)
    assert str(archive) in message and "'resources/table.bin'" in message and "limit of 1 MiB" in message
    assert "--max-unpacked" in message and safeio.MAX_UNPACKED_ENV in message
    ssp.load(archive, max_unpacked_bytes=8 * 1024**2).close()

    monkeypatch.setenv(safeio.MAX_UNPACKED_ENV, "1M")
    assert f"limit of 1 MiB (1048576 bytes, {safeio.MAX_UNPACKED_ENV})" in _refused(ssp.load, archive)
    assert main(["validate", str(archive), "--max-unpacked", "1.5M"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("cosim: error: ") and "limit of 1.5 MiB" in err and "--max-unpacked)" in err
    monkeypatch.setenv(safeio.MAX_UNPACKED_ENV, "lots")
    assert safeio.MAX_UNPACKED_ENV in _refused(ssp.load, archive)


def test_declared_sizes_that_lie_are_caught_while_extracting(tmp_path):
    """The header says 100 bytes, the data inflates to 1 MiB: at most 100 bytes are written,
    and the member is refused (its CRC is that of the whole content)."""
    content = bytes(range(256)) * 4096
    members = _scenario_members()
    archive = _raw_zip(tmp_path / "liar.ssp", members + [("resources/liar.bin", _deflate(content), 100,
                                                          zlib.crc32(content))])
    limit = sum(size for _, _, size, _ in members) + 1000
    message = _refused(ssp.load, archive, max_unpacked_bytes=limit)
    assert str(archive) in message and "'resources/liar.bin'" in message and "corrupt" in message

    # a liar whose CRC matches its first 100 bytes is read as those 100 bytes, never more
    archive = _raw_zip(tmp_path / "liar2.ssp", members + [("resources/liar.bin", _deflate(content), 100,
                                                           zlib.crc32(content[:100]))])
    structure = ssp.load(archive, max_unpacked_bytes=limit)
    try:
        assert (structure.base_dir / "resources" / "liar.bin").read_bytes() == content[:100]
    finally:
        structure.close()


@pytest.mark.parametrize("member, expected", [
    ("../evil.txt", "escapes the archive"),
    ("resources/../../evil.txt", "escapes the archive"),
    ("..\\evil.txt", "escapes the archive"),
    ("/tmp/evil.txt", "absolute path"),
    ("C:/evil.txt", "absolute path"),
    ("controller.ssv", "appears twice"),
])
def test_member_path_traversal_and_duplicates_are_refused(tmp_path, member, expected):
    archive = _scenario_archive(tmp_path / "bad.ssp")
    with zipfile.ZipFile(archive, "a") as z, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)     # zipfile warns of the duplicate we write on purpose
        z.writestr(member, "x")
    message = _refused(ssp.load, archive)
    assert str(archive) in message and f"'{member}'" in message and expected in message
    assert not (tmp_path / "evil.txt").exists()


@pytest.mark.parametrize("kind", ["symlink", "encrypted", "bzip2", "too many"])
def test_odd_members_are_refused(tmp_path, monkeypatch, kind):
    archive = _scenario_archive(tmp_path / "odd.ssp")
    info = zipfile.ZipInfo("resources/odd")
    if kind == "symlink":
        info.external_attr = (stat.S_IFLNK | 0o777) << 16
    elif kind == "bzip2":
        info.compress_type = zipfile.ZIP_BZIP2
    elif kind == "too many":
        monkeypatch.setattr(safeio, "MAX_MEMBERS", 3)
    with zipfile.ZipFile(archive, "a") as z:
        z.writestr(info, "/etc/passwd")
    if kind == "encrypted":   # zipfile writes no encrypted members: set bit 0 of the general purpose flag
        data = archive.read_bytes()
        entry = data.rindex(b"PK\x01\x02")          # the last central directory header (APPNOTE 4.3.12)
        archive.write_bytes(data[:entry + 8] + bytes([data[entry + 8] | 0x1]) + data[entry + 9:])
    message = _refused(ssp.load, archive)
    expected = {"symlink": "symbolic link", "encrypted": "encrypted", "bzip2": "compression method 12",
                "too many": "more than the 3"}[kind]
    assert str(archive) in message and expected in message


def test_entity_refusal_inside_an_archive_names_the_member(tmp_path):
    ssd = SSD_HEAD + BILLION_LAUGHS + MINIMAL_SSD.replace('name="x"', 'name="&lol9;"')
    archive = tmp_path / "laughs.ssp"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("SystemStructure.ssd", ssd)
    message = _refused(ssp.load, archive)
    assert f"{archive}!SystemStructure.ssd" in message and "entity declarations are not allowed" in message


def test_refused_archive_leaves_no_extracted_files(tmp_path, monkeypatch):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    archive = _scenario_archive(tmp_path / "bad.ssp", {"resources/big.bin": bytes(1000)})
    with zipfile.ZipFile(archive, "a") as z:
        z.writestr("resources/../../evil.txt", "x")
    _refused(ssp.load, archive)                                   # before extraction
    content = bytes(range(256)) * 64
    liar = _raw_zip(tmp_path / "liar.ssp", _scenario_members() + [("resources/liar.bin", _deflate(content), 10,
                                                                   zlib.crc32(content))])
    assert "corrupt" in _refused(ssp.load, liar)                 # while extracting
    truncated = tmp_path / "truncated.ssp"
    with zipfile.ZipFile(truncated, "w") as z:
        z.writestr("SystemStructure.ssd", MINIMAL_SSD[:50])
    assert "not well formed" in _refused(ssp.load, truncated)    # after extraction
    assert list(scratch.iterdir()) == []


def test_oversized_document_is_refused_before_parsing(tmp_path, monkeypatch):
    monkeypatch.setattr(safeio, "MAX_XML_BYTES", 1000)
    path = tmp_path / "big.ssd"
    path.write_text(SSD_HEAD + MINIMAL_SSD.replace("<ssd:System", "<ssd:System description='" + "x" * 2000 + "'"))
    message = _refused(ssp.load, path)
    assert str(path) in message and "larger than 1000 bytes" in message


def test_fmus_inside_an_archive_are_checked_too(tmp_path, built_fmus):
    scenario = Path("ssp/pid_fopdt")
    sources = sorted({el.get("source") for el in etree.parse(str(scenario / "SystemStructure.ssd")).iter()
                      if el.get("source", "").endswith(".fmu")})
    fmus = {source: built_fmus[Path(source).stem].read_bytes() for source in sources}
    ssp.load(_scenario_archive(tmp_path / "good.ssp", fmus)).close()    # real FMUs pass the checks

    # a member that is no zip archive is refused by the component that uses it, naming both
    # (tests/scenarios/test_master_errors.py::test_an_unusable_fmu_in_an_ssp_archive_names_its_component)
    broken = dict(fmus, **{sources[0]: b"MZ not a zip"})
    ssp.load(_scenario_archive(tmp_path / "broken.ssp", broken)).close()

    raw, size, crc = _zeros_bomb(1)
    bomb = _raw_zip(tmp_path / "bomb.fmu", [("modelDescription.xml", raw, size, crc)])
    nested = _scenario_archive(tmp_path / "nested.ssp", {s: data for s, data in fmus.items() if s != sources[0]})
    with zipfile.ZipFile(nested, "a") as z:
        z.writestr(zipfile.ZipInfo(sources[0]), bomb.read_bytes())     # stored: the outer ratio is 1
    message = _refused(ssp.load, nested)
    assert f"nested.ssp!{sources[0]}" in message and "'modelDescription.xml'" in message and "zip bomb" in message


@pytest.mark.parametrize("text", ["1e", "2.5E", "-1e+"])
def test_a_real_value_the_schema_passes_and_python_cannot_read_is_one_setup_error(tmp_path, text):
    """libxml2's xs:double takes '1e' (and the other texts here), Python's float() does not: an inline
    ssv:Real of '1e' raised ValueError from cosim.read.ssp (found by COSIM_FUZZ=nightly, 10 000 cases)."""
    value, message = f'<ssv:Real value="{text}"/>', f"ssv:Real value '{text}' is not a number."
    source = Path(__file__).resolve().parents[2] / "ssp" / "btg_boiler_following"
    shutil.copytree(source, tmp_path / "s")
    ssd = tmp_path / "s" / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('<ssv:Real value="0.15"/>', value, 1))
    with pytest.raises(SetupError) as caught:
        ssp.load(tmp_path / "s").close()
    assert message in str(caught.value) and "slope" in str(caught.value) and "SystemStructure.ssd" in str(caught.value)


def test_a_member_name_flagged_utf8_that_is_not_is_one_setup_error(tmp_path):
    """A zip member name with the UTF-8 flag (general purpose bit 11) and bytes that are not UTF-8:
    zipfile raised UnicodeDecodeError out of cosim.read.ssp.load (found by COSIM_FUZZ=nightly)."""
    path = tmp_path / "bad.ssp"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("SystemStructure.ssd", "<x/>")
        z.writestr("zz__name.txt", "data")
    data = bytearray(path.read_bytes().replace(b"zz__name", b"\xf4\x90\x80\x80name"))
    central = data.rindex(b"PK\x01\x02")            # the last member's central directory header
    data[central + 9] |= 0x08                         # general purpose flags, bit 11: the name is UTF-8
    path.write_bytes(bytes(data))
    with pytest.raises(SetupError, match="flagged UTF-8 and is not") as caught:
        ssp.load(path).close()
    assert "bad.ssp" in str(caught.value)
