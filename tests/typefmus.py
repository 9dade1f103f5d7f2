"""Model descriptions and C bodies (tests/cfmus.py) of the FMUs exchanging the FMI types beyond
Real, Integer and Boolean: Modes2 (FMI 2.0 Enumeration), Types3 (FMI 3.0 Float32, Int8, UInt16,
Int64, UInt64, Enumeration) and Bytes3 (FMI 3.0 Binary), for tests/cosim/test_fmi_types.py and
tests/scenarios/test_isolate.py."""

MODES2 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Modes2" guid="{9e0c0000-0000-4000-8000-000000000002}"
  numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="Modes2" canHandleVariableCommunicationStepSize="true"/>
  <TypeDefinitions><SimpleType name="Level"><Enumeration>
    <Item name="low" value="1"/><Item name="mid" value="2"/><Item name="high" value="3"/>
  </Enumeration></SimpleType></TypeDefinitions>
  <ModelVariables>
    <ScalarVariable name="mode" valueReference="0" causality="output" variability="discrete" initial="exact">
      <Enumeration declaredType="Level" start="1"/></ScalarVariable>
    <ScalarVariable name="set" valueReference="1" causality="input" variability="discrete">
      <Enumeration declaredType="Level" start="1"/></ScalarVariable>
    <ScalarVariable name="first" valueReference="2" causality="parameter" variability="fixed" initial="exact">
      <Enumeration declaredType="Level" start="1"/></ScalarVariable>
    <ScalarVariable name="echo" valueReference="3" causality="output" variability="discrete" initial="calculated">
      <Integer/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1" dependencies=""/><Unknown index="4" dependencies="2"/></Outputs>
  <InitialUnknowns><Unknown index="4" dependencies="2"/></InitialUnknowns></ModelStructure>
</fmiModelDescription>
"""


#: mode cycles through the items from ``first``, one per step; echo = 10·set
MODES2_BODY = """
static void start(S *s) { s->i[0] = 1; s->i[1] = 1; s->i[2] = 1; }
static void calculate(S *s) { s->i[3] = 10 * s->i[1]; if (s->i[62] == 0) s->i[0] = s->i[2]; }
static int step(S *s, double t, double h) { s->i[62] += 1; s->i[0] = (s->i[2] - 1 + s->i[62]) % 3 + 1; return 0; }
"""


TYPES3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Types3" instantiationToken="{9e0c0000-0000-4000-8000-000000000003}">
  <CoSimulation modelIdentifier="Types3" canHandleVariableCommunicationStepSize="true"/>
  <TypeDefinitions><EnumerationType name="Level">
    <Item name="low" value="1"/><Item name="mid" value="2"/><Item name="high" value="3"/>
  </EnumerationType></TypeDefinitions>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Float32 name="f" valueReference="0" causality="output" variability="continuous"/>
    <Int8 name="i8" valueReference="1" causality="output" variability="discrete"/>
    <UInt16 name="u16" valueReference="2" causality="output" variability="discrete"/>
    <Int64 name="i64" valueReference="3" causality="output" variability="discrete"/>
    <UInt64 name="u64" valueReference="4" causality="output" variability="discrete"/>
    <Enumeration name="e" declaredType="Level" valueReference="5" causality="output" variability="discrete"/>
    <Float32 name="fin" valueReference="10" causality="input" variability="continuous" start="0"/>
    <Int8 name="i8in" valueReference="11" causality="input" variability="discrete" start="0"/>
    <Int64 name="i64in" valueReference="13" causality="input" variability="discrete" start="0"/>
    <Enumeration name="ein" declaredType="Level" valueReference="15" causality="input" variability="discrete" start="1"/>
    <Float32 name="fecho" valueReference="20" causality="output" variability="continuous"/>
    <Int64 name="sum" valueReference="21" causality="output" variability="discrete"/>
    <UInt64 name="scale" valueReference="30" causality="parameter" variability="fixed" start="1"/>
    <Enumeration name="level" declaredType="Level" valueReference="31" causality="parameter" variability="fixed" start="1"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="0" dependencies=""/><Output valueReference="1" dependencies=""/>
    <Output valueReference="2" dependencies=""/><Output valueReference="3" dependencies=""/>
    <Output valueReference="4" dependencies=""/><Output valueReference="5" dependencies=""/>
    <Output valueReference="20" dependencies="10"/><Output valueReference="21" dependencies="11 13 15"/>
  </ModelStructure>
</fmiModelDescription>
"""


#: k = steps taken: f = 0.1 k (Float32), i8 = k − 5, u16 = 1000 k, i64 = 100000 k, u64 = scale·k,
#: e = k mod 3 + 1; fecho = 2·fin, sum = i8in + i64in + ein + 10·level
TYPES3_BODY = """
static void start(S *s) { s->l[15] = 1; s->l[30] = 1; s->l[31] = 1; }
static void calculate(S *s) {
    long long k = s->l[62];
    s->f[0] = 0.1f * (float) k; s->l[1] = k - 5; s->l[2] = 1000 * k; s->l[3] = 100000 * k;
    s->l[4] = (long long) ((unsigned long long) s->l[30] * (unsigned long long) k); s->l[5] = k % 3 + 1;
    s->f[20] = 2.0f * s->f[10]; s->l[21] = s->l[11] + s->l[13] + s->l[15] + 10 * s->l[31]; }
static int step(S *s, double t, double h) { s->l[62] += 1; return 0; }
"""


OUTPUTS3 = ["f", "i8", "u16", "i64", "u64", "e"]


BYTES3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Bytes3" instantiationToken="{9e0c0000-0000-4000-8000-000000000004}">
  <CoSimulation modelIdentifier="Bytes3" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Binary name="blob" valueReference="40" causality="output" variability="discrete"/>
    <Binary name="bin" valueReference="41" causality="input" variability="discrete"><Start value=""/></Binary>
    <Int32 name="length" valueReference="42" causality="output" variability="discrete"/>
    <Int32 name="checksum" valueReference="43" causality="output" variability="discrete"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="40" dependencies=""/><Output valueReference="42" dependencies="41"/>
    <Output valueReference="43" dependencies="41"/>
  </ModelStructure>
</fmiModelDescription>
"""


#: blob = k bytes of value k + 1 (k = steps taken, at most 16); length and checksum (the byte sum) of bin
BYTES3_BODY = """
static void start(S *s) {}
static void calculate(S *s) {
    int k = s->i[62] < 16 ? s->i[62] : 16;
    s->nbytes[40] = k; for (int j = 0; j < k; j++) s->bytes[40][j] = (unsigned char) (k + 1);
    s->i[42] = (int) s->nbytes[41]; int sum = 0; for (size_t j = 0; j < s->nbytes[41]; j++) sum += s->bytes[41][j];
    s->i[43] = sum; }
static int step(S *s, double t, double h) { s->i[62] += 1; return 0; }
"""
