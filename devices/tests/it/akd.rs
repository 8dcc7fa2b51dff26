//! Kollmorgen AKD servo drive: the EDS (`devices/kollmorgen-akd.eds`) and its sidecar checked
//! against the Italian CAN-BUS manual (`kollmorgen-akd-canbus-manual-it.txt`, Revision F,
//! March 2012).
//!
//! Every expected value below is taken from the manual; the comment names the section. Where
//! the EDS deliberately differs from a printed value (a reconciliation decision recorded in the
//! EDS `[Comments]` and the sidecar), the comment says so.

use devices::sidecar::{BusScaling, Dimension, ObjRef, Reaction, Remapping, ScalingKind, Sidecar, Unit};
use eds::{Access, Category, DataType, Model, ObjectType, Options, PdoMappingEntry, Value};

const EDS_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/kollmorgen-akd.eds");

fn load_with(options: &Options) -> eds::Parsed {
    eds::read_file(EDS_PATH, options).expect("devices/kollmorgen-akd.eds is readable")
}

fn model() -> Model {
    let parsed = load_with(&Options::lenient());
    let errors: Vec<_> = parsed.errors().collect();
    assert!(errors.is_empty(), "errors in kollmorgen-akd.eds: {errors:#?}");
    parsed.model
}

fn entry(m: &Model, index: u16, sub: u8) -> &eds::Entry {
    m.entry(index, sub).unwrap_or_else(|| panic!("0x{index:04X} sub {sub} missing"))
}

/// The integer default of `(index, sub)`, with `$NODEID` resolved for node 0.
fn default_int(m: &Model, index: u16, sub: u8) -> i128 {
    let e = entry(m, index, sub);
    e.default
        .as_ref()
        .and_then(|v| v.resolve(0))
        .unwrap_or_else(|| panic!("0x{index:04X} sub {sub} has no integer default: {:?}", e.default))
}

fn default_text(m: &Model, index: u16, sub: u8) -> String {
    match &entry(m, index, sub).default {
        Some(Value::Text(s)) => s.clone(),
        other => panic!("0x{index:04X} sub {sub}: expected text default, got {other:?}"),
    }
}

fn limits(m: &Model, index: u16, sub: u8) -> (Option<i128>, Option<i128>) {
    let e = entry(m, index, sub);
    (e.low_limit().and_then(Value::as_int), e.high_limit().and_then(Value::as_int))
}

fn dtype(m: &Model, index: u16, sub: u8) -> DataType {
    entry(m, index, sub).data_type
}

fn access(m: &Model, index: u16, sub: u8) -> Access {
    entry(m, index, sub).access
}

fn mappable(m: &Model, index: u16, sub: u8) -> bool {
    entry(m, index, sub).pdo_mapping
}

fn denotation(m: &Model, index: u16, sub: u8) -> Option<&str> {
    entry(m, index, sub).denotation()
}

/// Appendix 7.1.2: every index it lists (34).
const APPENDIX_7_1_2: &[u16] = &[
    0x1000, 0x1001, 0x1002, 0x1003, 0x1005, 0x1006, 0x1008, 0x1009, 0x100A, 0x100C, 0x100D, 0x1010, 0x1011, 0x1014,
    0x1016, 0x1017, 0x1018, 0x1026, 0x1400, 0x1401, 0x1402, 0x1403, 0x1600, 0x1601, 0x1602, 0x1603, 0x1800, 0x1801,
    0x1802, 0x1803, 0x1A00, 0x1A01, 0x1A02, 0x1A03,
];

/// Appendix 7.1.3: every index it lists (252).
const APPENDIX_7_1_3: &[u16] = &[
    0x2014, 0x2015, 0x2016, 0x2017, 0x2018, 0x204C, 0x2050, 0x2071, 0x2077, 0x20A0, 0x20A1, 0x20A2, 0x20A3, 0x20A4,
    0x20A5, 0x20A6, 0x20B8, 0x3405, 0x3406, 0x3407, 0x3412, 0x3414, 0x3415, 0x3416, 0x3420, 0x3421, 0x3422, 0x3423,
    0x3424, 0x3425, 0x3426, 0x3427, 0x3430, 0x3431, 0x3440, 0x3441, 0x3443, 0x3444, 0x3445, 0x3450, 0x3451, 0x3452,
    0x3453, 0x3454, 0x3455, 0x3456, 0x3457, 0x3460, 0x3470, 0x3471, 0x3472, 0x3474, 0x3475, 0x3480, 0x3481, 0x3482,
    0x3483, 0x3484, 0x3490, 0x3491, 0x3492, 0x3493, 0x3494, 0x3496, 0x34A0, 0x34A1, 0x34A2, 0x34A3, 0x34A4, 0x3501,
    0x3502, 0x3506, 0x3509, 0x3522, 0x3524, 0x352A, 0x3533, 0x3534, 0x3535, 0x3537, 0x353B, 0x3542, 0x3548, 0x354B,
    0x354D, 0x3558, 0x3559, 0x355A, 0x3562, 0x3565, 0x3568, 0x356B, 0x356E, 0x356F, 0x3586, 0x3587, 0x358E, 0x358F,
    0x3593, 0x3596, 0x3598, 0x359C, 0x359D, 0x35A3, 0x35A4, 0x35AB, 0x35AF, 0x35B2, 0x35B4, 0x35BC, 0x35C2, 0x35C5,
    0x35C6, 0x35C7, 0x35CA, 0x35CB, 0x35E2, 0x35EB, 0x35F0, 0x35FE, 0x35FF, 0x3610, 0x3611, 0x3612, 0x3617, 0x3618,
    0x361A, 0x361D, 0x3622, 0x3623, 0x3627, 0x3629, 0x3656, 0x3659, 0x365B, 0x365F, 0x3660, 0x366E, 0x366F, 0x3683,
    0x3685, 0x36D0, 0x36D1, 0x36D7, 0x36E2, 0x36E5, 0x36E6, 0x36E7, 0x36E8, 0x36E9, 0x36EA, 0x36EB, 0x36EC, 0x36ED,
    0x36EE, 0x36F6, 0x36F9, 0x36FC, 0x3856, 0x5000, 0x5001, 0x5002, 0x5003, 0x5009, 0x500B, 0x5013, 0x5015, 0x5016,
    0x5019, 0x5060, 0x5080, 0x5083, 0x5084, 0x5085, 0x508C, 0x508F, 0x5096, 0x5097, 0x5099, 0x509A, 0x509C, 0x50B1,
    0x50B7, 0x50B9, 0x50BB, 0x50BC, 0x50BE, 0x50E2, 0x50FB, 0x50FE, 0x5104, 0x510E, 0x5121, 0x5128, 0x5175, 0x5176,
    0x5177, 0x5179, 0x517A, 0x517E, 0x5184, 0x5187, 0x518A, 0x518E, 0x51AE, 0x51B0, 0x51B3, 0x51B8, 0x51BA, 0x51BB,
    0x51CB, 0x51CC, 0x51CD, 0x51CE, 0x51CF, 0x51D0, 0x51D1, 0x51E7, 0x51E8, 0x51E9, 0x51EC, 0x51ED, 0x51EE, 0x51EF,
    0x51F0, 0x520C, 0x520D, 0x520E, 0x5251, 0x5252, 0x5253, 0x5254, 0x5255, 0x5256, 0x5257, 0x5258, 0x5259, 0x525A,
    0x525B, 0x525C, 0x525D, 0x525E, 0x525F, 0x5260, 0x5261, 0x5262, 0x5263, 0x5264, 0x5265, 0x5266, 0x5267, 0x5268,
];

/// Appendix 7.1.4: every index it lists (45).
const APPENDIX_7_1_4: &[u16] = &[
    0x6040, 0x6041, 0x6060, 0x6061, 0x6063, 0x6064, 0x6065, 0x606B, 0x606C, 0x606D, 0x606E, 0x6071, 0x6072, 0x6073,
    0x6077, 0x607A, 0x607C, 0x607D, 0x6081, 0x6083, 0x6084, 0x608F, 0x6091, 0x6092, 0x6098, 0x6099, 0x609A, 0x60B1,
    0x60B2, 0x60B8, 0x60B9, 0x60BA, 0x60BB, 0x60BC, 0x60BD, 0x60C0, 0x60C1, 0x60C2, 0x60C4, 0x60D0, 0x60F4, 0x60FD,
    0x60FE, 0x60FF, 0x6502,
];

/// Appendix 7.1.2: every (index, sub-index) row, "1 a 8" ranges expanded (145).
#[rustfmt::skip]
const APPENDIX_7_1_2_SUBS: &[(u16, u8)] = &[
    (0x1000, 0), (0x1001, 0), (0x1002, 0), (0x1003, 0), (0x1003, 1), (0x1003, 2), (0x1003, 3), (0x1003, 4),
    (0x1003, 5), (0x1003, 6), (0x1003, 7), (0x1003, 8), (0x1003, 9), (0x1003, 10), (0x1005, 0), (0x1006, 0),
    (0x1008, 0), (0x1009, 0), (0x100A, 0), (0x100C, 0), (0x100D, 0), (0x1010, 0), (0x1010, 1), (0x1011, 0),
    (0x1011, 1), (0x1014, 0), (0x1016, 0), (0x1016, 1), (0x1017, 0), (0x1018, 0), (0x1018, 1), (0x1018, 2),
    (0x1018, 3), (0x1018, 4), (0x1026, 0), (0x1026, 1), (0x1026, 2), (0x1400, 0), (0x1400, 1), (0x1400, 2),
    (0x1401, 0), (0x1401, 1), (0x1401, 2), (0x1402, 0), (0x1402, 1), (0x1402, 2), (0x1403, 0), (0x1403, 1),
    (0x1403, 2), (0x1600, 0), (0x1600, 1), (0x1600, 2), (0x1600, 3), (0x1600, 4), (0x1600, 5), (0x1600, 6),
    (0x1600, 7), (0x1600, 8), (0x1601, 0), (0x1601, 1), (0x1601, 2), (0x1601, 3), (0x1601, 4), (0x1601, 5),
    (0x1601, 6), (0x1601, 7), (0x1601, 8), (0x1602, 0), (0x1602, 1), (0x1602, 2), (0x1602, 3), (0x1602, 4),
    (0x1602, 5), (0x1602, 6), (0x1602, 7), (0x1602, 8), (0x1603, 0), (0x1603, 1), (0x1603, 2), (0x1603, 3),
    (0x1603, 4), (0x1603, 5), (0x1603, 6), (0x1603, 7), (0x1603, 8), (0x1800, 0), (0x1800, 1), (0x1800, 2),
    (0x1800, 3), (0x1800, 4), (0x1800, 5), (0x1801, 0), (0x1801, 1), (0x1801, 2), (0x1801, 3), (0x1801, 4),
    (0x1801, 5), (0x1802, 0), (0x1802, 1), (0x1802, 2), (0x1802, 3), (0x1802, 4), (0x1802, 5), (0x1803, 0),
    (0x1803, 1), (0x1803, 2), (0x1803, 3), (0x1803, 4), (0x1803, 5), (0x1A00, 0), (0x1A00, 1), (0x1A00, 2),
    (0x1A00, 3), (0x1A00, 4), (0x1A00, 5), (0x1A00, 6), (0x1A00, 7), (0x1A00, 8), (0x1A01, 0), (0x1A01, 1),
    (0x1A01, 2), (0x1A01, 3), (0x1A01, 4), (0x1A01, 5), (0x1A01, 6), (0x1A01, 7), (0x1A01, 8), (0x1A02, 0),
    (0x1A02, 1), (0x1A02, 2), (0x1A02, 3), (0x1A02, 4), (0x1A02, 5), (0x1A02, 6), (0x1A02, 7), (0x1A02, 8),
    (0x1A03, 0), (0x1A03, 1), (0x1A03, 2), (0x1A03, 3), (0x1A03, 4), (0x1A03, 5), (0x1A03, 6), (0x1A03, 7),
    (0x1A03, 8),
];

/// Appendix 7.1.3: every (index, sub-index) row, "1 a 8" ranges expanded (368).
#[rustfmt::skip]
const APPENDIX_7_1_3_SUBS: &[(u16, u8)] = &[
    (0x2014, 1), (0x2014, 2), (0x2015, 1), (0x2015, 2), (0x2016, 1), (0x2016, 2), (0x2017, 1), (0x2017, 2),
    (0x2018, 0), (0x2018, 1), (0x2018, 2), (0x2018, 3), (0x2018, 4), (0x204C, 0), (0x204C, 1), (0x204C, 2),
    (0x2050, 0), (0x2071, 0), (0x2077, 0), (0x20A0, 0), (0x20A1, 0), (0x20A2, 0), (0x20A3, 0), (0x20A4, 0),
    (0x20A5, 0), (0x20A6, 0), (0x20B8, 0), (0x3405, 0), (0x3405, 1), (0x3405, 2), (0x3405, 3), (0x3405, 4),
    (0x3406, 0), (0x3406, 1), (0x3406, 2), (0x3406, 3), (0x3406, 4), (0x3406, 5), (0x3406, 6), (0x3406, 7),
    (0x3406, 8), (0x3406, 9), (0x3406, 10), (0x3406, 11), (0x3406, 12), (0x3406, 13), (0x3406, 14), (0x3406, 15),
    (0x3406, 16), (0x3407, 0), (0x3407, 1), (0x3407, 2), (0x3407, 3), (0x3407, 4), (0x3412, 0), (0x3414, 0),
    (0x3415, 0), (0x3416, 0), (0x3420, 0), (0x3421, 0), (0x3422, 0), (0x3423, 0), (0x3424, 0), (0x3425, 0),
    (0x3426, 0), (0x3427, 0), (0x3427, 1), (0x3427, 2), (0x3427, 3), (0x3430, 0), (0x3431, 0), (0x3440, 0),
    (0x3440, 1), (0x3440, 2), (0x3440, 3), (0x3441, 0), (0x3443, 0), (0x3444, 0), (0x3445, 0), (0x3450, 0),
    (0x3451, 0), (0x3452, 0), (0x3453, 0), (0x3454, 0), (0x3455, 0), (0x3456, 0), (0x3457, 0), (0x3457, 1),
    (0x3457, 2), (0x3457, 3), (0x3460, 0), (0x3460, 1), (0x3460, 2), (0x3460, 3), (0x3460, 4), (0x3460, 5),
    (0x3460, 6), (0x3460, 7), (0x3460, 8), (0x3460, 9), (0x3460, 10), (0x3470, 0), (0x3470, 1), (0x3470, 2),
    (0x3470, 3), (0x3470, 4), (0x3470, 5), (0x3471, 0), (0x3472, 0), (0x3474, 0), (0x3474, 1), (0x3474, 2),
    (0x3474, 3), (0x3474, 4), (0x3474, 5), (0x3474, 6), (0x3474, 7), (0x3474, 8), (0x3474, 9), (0x3474, 10),
    (0x3474, 11), (0x3474, 12), (0x3474, 13), (0x3474, 14), (0x3475, 0), (0x3475, 1), (0x3475, 2), (0x3475, 3),
    (0x3475, 4), (0x3480, 0), (0x3481, 0), (0x3481, 1), (0x3481, 2), (0x3482, 0), (0x3483, 0), (0x3484, 0),
    (0x3490, 0), (0x3491, 0), (0x3492, 0), (0x3493, 0), (0x3494, 0), (0x3494, 1), (0x3494, 2), (0x3494, 3),
    (0x3494, 4), (0x3494, 5), (0x3494, 6), (0x3496, 0), (0x3496, 1), (0x3496, 2), (0x3496, 3), (0x3496, 4),
    (0x34A0, 0), (0x34A0, 1), (0x34A0, 2), (0x34A0, 3), (0x34A0, 4), (0x34A0, 5), (0x34A0, 6), (0x34A0, 7),
    (0x34A0, 8), (0x34A1, 0), (0x34A1, 1), (0x34A1, 2), (0x34A1, 3), (0x34A1, 4), (0x34A1, 5), (0x34A1, 6),
    (0x34A1, 7), (0x34A1, 8), (0x34A2, 0), (0x34A2, 1), (0x34A2, 2), (0x34A2, 3), (0x34A2, 4), (0x34A2, 5),
    (0x34A2, 6), (0x34A2, 7), (0x34A2, 8), (0x34A3, 0), (0x34A3, 1), (0x34A3, 2), (0x34A3, 3), (0x34A3, 4),
    (0x34A4, 0), (0x3501, 0), (0x3502, 0), (0x3506, 0), (0x3509, 0), (0x3522, 0), (0x3524, 0), (0x352A, 0),
    (0x3533, 0), (0x3534, 0), (0x3535, 0), (0x3537, 0), (0x353B, 0), (0x3542, 0), (0x3548, 0), (0x354B, 0),
    (0x354D, 0), (0x3558, 0), (0x3559, 0), (0x355A, 0), (0x3562, 0), (0x3565, 0), (0x3568, 0), (0x356B, 0),
    (0x356E, 0), (0x356F, 0), (0x3586, 0), (0x3587, 0), (0x358E, 0), (0x358F, 0), (0x3593, 0), (0x3596, 0),
    (0x3598, 0), (0x359C, 0), (0x359D, 0), (0x35A3, 0), (0x35A4, 0), (0x35AB, 0), (0x35AF, 0), (0x35B2, 0),
    (0x35B4, 0), (0x35BC, 0), (0x35C2, 0), (0x35C5, 0), (0x35C6, 0), (0x35C7, 0), (0x35CA, 0), (0x35CB, 0),
    (0x35E2, 0), (0x35EB, 0), (0x35F0, 0), (0x35FE, 0), (0x35FF, 0), (0x3610, 0), (0x3611, 0), (0x3612, 0),
    (0x3617, 0), (0x3618, 0), (0x361A, 0), (0x361D, 0), (0x3622, 0), (0x3623, 0), (0x3627, 0), (0x3629, 0),
    (0x3656, 0), (0x3659, 0), (0x365B, 0), (0x365F, 0), (0x3660, 0), (0x366E, 0), (0x366F, 0), (0x3683, 0),
    (0x3685, 0), (0x36D0, 0), (0x36D1, 0), (0x36D7, 0), (0x36E2, 0), (0x36E5, 0), (0x36E6, 0), (0x36E7, 0),
    (0x36E8, 0), (0x36E9, 0), (0x36EA, 0), (0x36EB, 0), (0x36EC, 0), (0x36ED, 0), (0x36EE, 0), (0x36F6, 0),
    (0x36F9, 0), (0x36FC, 0), (0x3856, 0), (0x5000, 0), (0x5001, 0), (0x5002, 0), (0x5003, 0), (0x5009, 0),
    (0x500B, 0), (0x5013, 0), (0x5015, 0), (0x5016, 0), (0x5019, 0), (0x5060, 0), (0x5080, 0), (0x5083, 0),
    (0x5084, 0), (0x5085, 0), (0x508C, 0), (0x508F, 0), (0x5096, 0), (0x5097, 0), (0x5099, 0), (0x509A, 0),
    (0x509C, 0), (0x50B1, 0), (0x50B7, 0), (0x50B9, 0), (0x50BB, 0), (0x50BC, 0), (0x50BE, 0), (0x50E2, 0),
    (0x50FB, 0), (0x50FE, 0), (0x5104, 0), (0x510E, 0), (0x5121, 0), (0x5128, 0), (0x5175, 0), (0x5176, 0),
    (0x5177, 0), (0x5179, 0), (0x517A, 0), (0x517E, 0), (0x5184, 0), (0x5187, 0), (0x518A, 0), (0x518E, 0),
    (0x51AE, 0), (0x51B0, 0), (0x51B3, 0), (0x51B8, 0), (0x51BA, 0), (0x51BB, 0), (0x51CB, 0), (0x51CC, 0),
    (0x51CD, 0), (0x51CE, 0), (0x51CF, 0), (0x51D0, 0), (0x51D1, 0), (0x51E7, 0), (0x51E8, 0), (0x51E9, 0),
    (0x51EC, 0), (0x51ED, 0), (0x51EE, 0), (0x51EF, 0), (0x51F0, 0), (0x520C, 0), (0x520D, 0), (0x520E, 0),
    (0x5251, 0), (0x5252, 0), (0x5253, 0), (0x5254, 0), (0x5255, 0), (0x5256, 0), (0x5257, 0), (0x5258, 0),
    (0x5259, 0), (0x525A, 0), (0x525B, 0), (0x525C, 0), (0x525D, 0), (0x525E, 0), (0x525F, 0), (0x5260, 0),
    (0x5261, 0), (0x5262, 0), (0x5263, 0), (0x5264, 0), (0x5265, 0), (0x5266, 0), (0x5267, 0), (0x5268, 0),
];

/// Appendix 7.1.4: every (index, sub-index) row, "1 a 8" ranges expanded (70).
#[rustfmt::skip]
const APPENDIX_7_1_4_SUBS: &[(u16, u8)] = &[
    (0x6040, 0), (0x6041, 0), (0x6060, 0), (0x6061, 0), (0x6063, 0), (0x6064, 0), (0x6065, 0), (0x606B, 0),
    (0x606C, 0), (0x606D, 0), (0x606E, 0), (0x6071, 0), (0x6072, 0), (0x6073, 0), (0x6077, 0), (0x607A, 0),
    (0x607C, 0), (0x607D, 0), (0x607D, 1), (0x607D, 2), (0x6081, 0), (0x6083, 0), (0x6084, 0), (0x608F, 0),
    (0x608F, 1), (0x608F, 2), (0x6091, 0), (0x6091, 1), (0x6091, 2), (0x6092, 0), (0x6092, 1), (0x6092, 2),
    (0x6098, 0), (0x6099, 0), (0x6099, 1), (0x6099, 2), (0x609A, 0), (0x60B1, 0), (0x60B2, 0), (0x60B8, 0),
    (0x60B9, 0), (0x60BA, 0), (0x60BB, 0), (0x60BC, 0), (0x60BD, 0), (0x60C0, 0), (0x60C1, 0), (0x60C1, 1),
    (0x60C1, 2), (0x60C1, 3), (0x60C2, 0), (0x60C2, 1), (0x60C2, 2), (0x60C4, 0), (0x60C4, 1), (0x60C4, 2),
    (0x60C4, 3), (0x60C4, 4), (0x60C4, 5), (0x60C4, 6), (0x60D0, 0), (0x60D0, 1), (0x60D0, 2), (0x60F4, 0),
    (0x60FD, 0), (0x60FE, 0), (0x60FE, 1), (0x60FE, 2), (0x60FF, 0), (0x6502, 0),
];

/// Described in chapter 6 (6.2.2.3) but missing from the appendix.
const CHAPTER_6_ONLY: &[u16] = &[0x2026];

/// Used only by the 7.2.2.1 frame listing (dummy mapping entry, decision in the EDS).
const EXAMPLE_ONLY: &[u16] = &[0x2100];

/// Every object of chapter 6 that has its own description (6.2 to 6.11).
const CHAPTER_6: &[u16] = &[
    0x1000, 0x1001, 0x1002, 0x1003, 0x1005, 0x1006, 0x1008, 0x1009, 0x100A, 0x100C, 0x100D, 0x1010, 0x1011, 0x1014,
    0x1016, 0x1017, 0x1018, 0x1026, 0x2014, 0x2015, 0x2016, 0x2017, 0x2018, 0x2026, 0x20A0, 0x20A1, 0x20A2, 0x20A3,
    0x20A4, 0x20A5, 0x20A6, 0x20B8, 0x3474, 0x3475, 0x3496, 0x60B8, 0x60B9, 0x60BA, 0x60BB, 0x60BC, 0x60BD, 0x60D0,
    0x60FD, 0x60FE, 0x6502, 0x1400, 0x1401, 0x1402, 0x1403, 0x1600, 0x1601, 0x1602, 0x1603, 0x1800, 0x1801, 0x1802,
    0x1803, 0x1A00, 0x1A01, 0x1A02, 0x1A03, 0x6040, 0x6041, 0x6060, 0x6061, 0x204C, 0x608F, 0x6091, 0x6092, 0x606C,
    0x60FF, 0x2071, 0x2077, 0x6071, 0x6073, 0x6077, 0x6063, 0x6064, 0x6065, 0x60F4, 0x60C0, 0x60C1, 0x60C2, 0x60C4,
    0x607C, 0x6098, 0x6099, 0x609A, 0x607A, 0x607D, 0x6081, 0x6083, 0x6084,
];

#[test]
fn every_appendix_and_chapter_6_object_is_present() {
    let m = model();
    for &i in APPENDIX_7_1_2.iter().chain(APPENDIX_7_1_3).chain(APPENDIX_7_1_4).chain(CHAPTER_6) {
        assert!(m.object(i).is_some(), "object 0x{i:04X} from the manual is missing");
    }
    // 7.1.2 + 7.1.3 + 7.1.4 list 331 distinct indices
    assert_eq!(APPENDIX_7_1_2.len() + APPENDIX_7_1_3.len() + APPENDIX_7_1_4.len(), 331);
    for &i in CHAPTER_6_ONLY.iter().chain(EXAMPLE_ONLY) {
        assert!(m.object(i).is_some(), "0x{i:04X}");
        assert!(!APPENDIX_7_1_3.contains(&i));
    }
    // nothing beyond the manual
    assert_eq!(m.objects.len(), 331 + CHAPTER_6_ONLY.len() + EXAMPLE_ONLY.len());
}

#[test]
fn every_appendix_sub_index_is_present() {
    let m = model();
    let all = APPENDIX_7_1_2_SUBS.iter().chain(APPENDIX_7_1_3_SUBS).chain(APPENDIX_7_1_4_SUBS);
    for &(i, s) in all {
        assert!(m.entry(i, s).is_some(), "0x{i:04X} sub {s} from the appendix is missing");
    }
    // sub-indices the appendix omits and chapter 6 / CiA 301 add (decisions in the EDS)
    for i in 0x2014..=0x2017 {
        assert_eq!(default_int(&m, i, 0), 2, "0x{i:04X}");
    }
    for s in 0..=2 {
        assert!(m.entry(0x2026, s).is_some());
    }
    // every ARRAY/RECORD: sub 0 is UNSIGNED8 and holds the highest sub-index, subs contiguous
    for (idx, o) in &m.objects {
        if !o.object_type.has_subs() {
            continue;
        }
        let top = *o.subs.keys().last().unwrap();
        assert_eq!(o.subs.len(), top.0 as usize + 1, "0x{:04X} has gaps", idx.0);
        assert_eq!(o.sub(0).unwrap().data_type, DataType::Unsigned8, "0x{:04X}", idx.0);
        if ![0x1003, 0x1600, 0x1601, 0x1602, 0x1603, 0x1A00, 0x1A01, 0x1A02, 0x1A03].contains(&idx.0) {
            assert_eq!(default_int(&m, idx.0, 0), top.0 as i128, "0x{:04X}", idx.0);
        }
    }
}

#[test]
fn object_lists_and_categories() {
    let m = model();
    for (idx, o) in &m.objects {
        let want = match idx.0 {
            0x1000 | 0x1001 | 0x1018 => Category::Mandatory,
            0x2000..=0x5FFF => Category::Manufacturer,
            _ => Category::Optional,
        };
        assert_eq!(o.category, want, "0x{:04X}", idx.0);
    }
}

#[test]
fn communication_objects_chapter_6_2_1() {
    let m = model();
    // 6.2.1.1: a read of 1000h returns 0x00020192 (profile 402, type 2)
    assert_eq!(default_int(&m, 0x1000, 0), 0x0002_0192);
    assert_eq!(access(&m, 0x1000, 0), Access::Ro);
    // 6.2.1.2: 1001h UNSIGNED8 ro
    assert_eq!(dtype(&m, 0x1001, 0), DataType::Unsigned8);
    // 6.2.1.3: 1002h UNSIGNED32 ro, PDO mapping possible
    assert_eq!(dtype(&m, 0x1002, 0), DataType::Unsigned32);
    assert!(mappable(&m, 0x1002, 0));
    // 6.2.1.4: 1003h, ten entries, sub0 range 0 to 10, default 0
    assert_eq!(m.object(0x1003).unwrap().object_type, ObjectType::Array);
    assert_eq!(m.object(0x1003).unwrap().subs.len(), 11);
    assert_eq!(limits(&m, 0x1003, 0), (Some(0), Some(10)));
    assert_eq!(default_int(&m, 0x1003, 0), 0);
    assert_eq!(access(&m, 0x1003, 0), Access::Rw);
    assert_eq!(access(&m, 0x1003, 10), Access::Ro);
    // 6.2.1.6: 1006h default 00h
    assert_eq!(default_int(&m, 0x1006, 0), 0);
    // 6.2.1.7 to 6.2.1.9: strings, const
    for i in [0x1008, 0x1009, 0x100A] {
        assert_eq!(dtype(&m, i, 0), DataType::VisibleString);
        assert_eq!(access(&m, i, 0), Access::Const);
    }
    // 6.2.1.10 / 6.2.1.11: guard time U16 0, life time factor U8 0
    assert_eq!((dtype(&m, 0x100C, 0), default_int(&m, 0x100C, 0)), (DataType::Unsigned16, 0));
    assert_eq!((dtype(&m, 0x100D, 0), default_int(&m, 0x100D, 0)), (DataType::Unsigned8, 0));
    // 6.2.1.12: 1010h sub0 1, sub1 default 1 (saves on command), DRV.NVSAVE
    assert_eq!(default_int(&m, 0x1010, 0), 1);
    assert_eq!(default_int(&m, 0x1010, 1), 1);
    assert_eq!(denotation(&m, 0x1010, 1), Some("DRV.NVSAVE"));
    // 6.2.1.12: "save" is unsigned32 0x65766173
    assert_eq!(u32::from_le_bytes(*b"save"), 0x6576_6173);
    // 6.2.1.13: 1011h sub1 default 1, DRV.NVLOAD; "load" is 0x64616F6C
    assert_eq!(default_int(&m, 0x1011, 1), 1);
    assert_eq!(denotation(&m, 0x1011, 1), Some("DRV.NVLOAD"));
    assert_eq!(u32::from_le_bytes(*b"load"), 0x6461_6F6C);
    // 6.2.1.14: 1014h default 80h + node id
    let emcy = entry(&m, 0x1014, 0).default.clone().unwrap();
    assert!(emcy.is_node_relative());
    assert_eq!(emcy.resolve(3), Some(0x83));
    // 6.2.1.15 / 6.2.1.16: consumer heartbeat sub0 1, sub1 U32; producer heartbeat U16 0
    assert_eq!(default_int(&m, 0x1016, 0), 1);
    assert_eq!(dtype(&m, 0x1016, 1), DataType::Unsigned32);
    assert_eq!((dtype(&m, 0x1017, 0), default_int(&m, 0x1017, 0)), (DataType::Unsigned16, 0));
    // 6.2.1.17: identity sub0 4, vendor 0x6A; revision example 0x00140000 (CAN version 0.20)
    assert_eq!(default_int(&m, 0x1018, 0), 4);
    assert_eq!(default_int(&m, 0x1018, 1), 0x6A);
    assert_eq!(default_int(&m, 0x1018, 3), 0x0014_0000);
    // 6.2.1.17: product code example M006 as four ASCII characters (decision: byte order)
    assert_eq!(default_int(&m, 0x1018, 2), u32::from_le_bytes(*b"M006") as i128);
    assert_eq!(default_text(&m, 0x1008, 0), "M006");
    // 6.2.1.18: 1026h sub0 2, StdIn U8 wo, StdOut U8 ro
    assert_eq!(default_int(&m, 0x1026, 0), 2);
    assert_eq!((dtype(&m, 0x1026, 1), access(&m, 0x1026, 1)), (DataType::Unsigned8, Access::Wo));
    assert_eq!((dtype(&m, 0x1026, 2), access(&m, 0x1026, 2)), (DataType::Unsigned8, Access::Ro));
}

#[test]
fn pdo_configuration_chapter_6_3() {
    let m = model();
    for n in 0..4u16 {
        // 6.3.1.1: RXPDO sub0 2, COB-ID 200h/300h/400h/500h + node id, type FFh
        assert_eq!(default_int(&m, 0x1400 + n, 0), 2);
        let cob = entry(&m, 0x1400 + n, 1).default.clone().unwrap();
        assert!(cob.is_node_relative());
        assert_eq!(cob.resolve(3), Some(0x203 + 0x100 * n as i128), "RXPDO{}", n + 1);
        assert_eq!(default_int(&m, 0x1400 + n, 2), 0xFF);
        // 6.3.2.1: TXPDO sub0 5, COB-ID 180h/280h/380h/480h + node id, type FFh, inhibit 0, timer 0
        assert_eq!(default_int(&m, 0x1800 + n, 0), 5);
        assert_eq!(entry(&m, 0x1800 + n, 1).default.as_ref().unwrap().resolve(3), Some(0x183 + 0x100 * n as i128));
        assert_eq!(default_int(&m, 0x1800 + n, 2), 0xFF);
        assert_eq!((dtype(&m, 0x1800 + n, 3), default_int(&m, 0x1800 + n, 3)), (DataType::Unsigned16, 0));
        assert_eq!((dtype(&m, 0x1800 + n, 4), access(&m, 0x1800 + n, 4)), (DataType::Unsigned8, Access::Const));
        assert_eq!((dtype(&m, 0x1800 + n, 5), default_int(&m, 0x1800 + n, 5)), (DataType::Unsigned16, 0));
        // 6.3.1.2 / 6.3.2.2: sub0 R/W, eight entries
        for map in [0x1600 + n, 0x1A00 + n] {
            assert_eq!(access(&m, map, 0), Access::Rw);
            assert_eq!(limits(&m, map, 0), (Some(0), Some(8)));
            assert_eq!(m.object(map).unwrap().subs.len(), 9);
        }
    }
    // 6.3.1.3: RXPDO defaults
    let rx: [&[u32]; 4] =
        [&[0x6040_0010], &[0x6040_0010, 0x6060_0008], &[0x6040_0010, 0x607A_0020], &[0x6040_0010, 0x60FF_0020]];
    // 6.3.2.3: TXPDO defaults
    let tx: [&[u32]; 4] =
        [&[0x6041_0010], &[0x6041_0010, 0x6061_0008], &[0x6041_0010, 0x6064_0020], &[0x6041_0010, 0x606C_0020]];
    for n in 0..4u16 {
        for (base, want) in [(0x1600u16, rx[n as usize]), (0x1A00, tx[n as usize])] {
            assert_eq!(default_int(&m, base + n, 0), want.len() as i128, "0x{:04X}", base + n);
            for s in 1..=8u8 {
                let v = want.get(s as usize - 1).copied().unwrap_or(0);
                assert_eq!(default_int(&m, base + n, s), v as i128, "0x{:04X} sub {s}", base + n);
            }
        }
    }
}

#[test]
fn default_pdo_mappings_are_consistent() {
    let m = model();
    for (map, rx) in (0..4u16).map(|n| (0x1600 + n, true)).chain((0..4u16).map(|n| (0x1A00 + n, false))) {
        let count = default_int(&m, map, 0) as u8;
        let mut bits = 0u32;
        for s in 1..=count {
            let e = PdoMappingEntry::from_u32(default_int(&m, map, s) as u32);
            let target = m.entry(e.index.0, e.sub.0).expect("mapped object exists");
            assert!(target.pdo_mapping, "0x{map:04X} maps a non-mappable object");
            assert_eq!(Some(e.bits as u32), target.data_type.bits());
            assert!(if rx { target.access.rpdo_ok() } else { target.access.tpdo_ok() }, "0x{map:04X} sub {s}");
            bits += e.bits as u32;
        }
        assert!(bits <= 64);
    }
}

#[test]
fn manufacturer_objects_chapter_6_2_2() {
    let m = model();
    // 6.2.2.1: transmit masks default FFFFFFFFh, rw, not mappable
    for i in 0x2014..=0x2017 {
        for s in 1..=2 {
            assert_eq!(default_int(&m, i, s), 0xFFFF_FFFF);
            assert_eq!(access(&m, i, s), Access::Rw);
            assert!(!mappable(&m, i, s));
        }
    }
    // 6.2.2.2: firmware version, four UNSIGNED16, default 0
    for s in 1..=4 {
        assert_eq!((dtype(&m, 0x2018, s), default_int(&m, 0x2018, s)), (DataType::Unsigned16, 0));
    }
    // 6.2.2.3: ASCII channel, command wo, response ro, visible strings
    assert_eq!((dtype(&m, 0x2026, 1), access(&m, 0x2026, 1)), (DataType::VisibleString, Access::Wo));
    assert_eq!((dtype(&m, 0x2026, 2), access(&m, 0x2026, 2)), (DataType::VisibleString, Access::Ro));
    // 6.2.2.4 to 6.2.2.7, 6.2.2.10: latch positions INTEGER32 ro mappable, default 0
    for i in [0x20A0, 0x20A1, 0x20A2, 0x20A3, 0x20A6] {
        assert_eq!((dtype(&m, i, 0), access(&m, i, 0)), (DataType::Integer32, Access::Ro), "0x{i:04X}");
        assert!(mappable(&m, i, 0));
        assert_eq!(default_int(&m, i, 0), 0);
    }
    assert_eq!(denotation(&m, 0x20A2, 0), Some("CAP1.PLFB, CAP1.T"));
    // 6.2.2.8 / 6.2.2.9: latch control rww, latch status rwr, UNSIGNED16, mappable
    assert_eq!((dtype(&m, 0x20A4, 0), access(&m, 0x20A4, 0)), (DataType::Unsigned16, Access::Rww));
    assert_eq!((dtype(&m, 0x20A5, 0), access(&m, 0x20A5, 0)), (DataType::Unsigned16, Access::Rwr));
    assert!(mappable(&m, 0x20A4, 0) && mappable(&m, 0x20A5, 0));
    // 6.2.2.11: 20B8h UNSIGNED16 rw mappable
    assert_eq!((dtype(&m, 0x20B8, 0), access(&m, 0x20B8, 0)), (DataType::Unsigned16, Access::Rw));
    assert!(mappable(&m, 0x20B8, 0));
    // 6.2.2.12: 3474h sub0 0xE, subs 1 to 0xE UNSIGNED32 rw default 0
    assert_eq!(default_int(&m, 0x3474, 0), 0xE);
    assert_eq!(denotation(&m, 0x3474, 1), Some("DIN1.PARAM"));
    assert_eq!(denotation(&m, 0x3474, 0xE), Some("DIN7.PARAM"));
    // 6.2.2.13: 3475h sub0 0x4
    assert_eq!(default_int(&m, 0x3475, 0), 4);
    assert_eq!(denotation(&m, 0x3475, 3), Some("DOUT1.PARAM"));
    // 6.2.2.14: FBUS sync parameters 320000, 320000, 70000, 150 ns
    assert_eq!(default_int(&m, 0x3496, 1), 320_000);
    assert_eq!(default_int(&m, 0x3496, 2), 320_000);
    assert_eq!(default_int(&m, 0x3496, 3), 70_000);
    assert_eq!(default_int(&m, 0x3496, 4), 150);
    assert_eq!(denotation(&m, 0x3496, 1), Some("FBUS.SYNCDIST"));
    assert_eq!(denotation(&m, 0x3496, 4), Some("FBUS.COMPTIME"));
    // 6.5.2.1: pv scaling factor INTEGER32, +1/+1, range -32768..32767
    for s in 1..=2 {
        assert_eq!((dtype(&m, 0x204C, s), default_int(&m, 0x204C, s)), (DataType::Integer32, 1));
        assert_eq!(limits(&m, 0x204C, s), (Some(-32768), Some(32767)));
    }
    // 6.7.2.1 / 6.7.2.2: target current rw, current actual ro, INTEGER32 mappable
    assert_eq!((dtype(&m, 0x2071, 0), access(&m, 0x2071, 0)), (DataType::Integer32, Access::Rw));
    assert_eq!((dtype(&m, 0x2077, 0), access(&m, 0x2077, 0)), (DataType::Integer32, Access::Ro));
    assert!(mappable(&m, 0x2071, 0) && mappable(&m, 0x2077, 0));
}

#[test]
fn appendix_7_1_3_rows() {
    let m = model();
    // 7.1.3: a sample of rows, type / access / ASCII name as printed
    assert_eq!((dtype(&m, 0x2050, 0), access(&m, 0x2050, 0)), (DataType::Integer32, Access::Ro));
    assert_eq!(denotation(&m, 0x2050, 0), Some("DRV.HANDWHEEL"));
    assert_eq!(dtype(&m, 0x3406, 0x10), DataType::Unsigned32);
    assert_eq!(denotation(&m, 0x3406, 0x10), Some("VL.ARZQ4"));
    assert_eq!(denotation(&m, 0x3405, 4), Some("VL.ARTYPE4"));
    assert_eq!((dtype(&m, 0x3407, 1), denotation(&m, 0x3407, 1)), (DataType::Integer32, Some("VL.FBFILTER")));
    assert_eq!((dtype(&m, 0x3407, 2), denotation(&m, 0x3407, 2)), (DataType::Unsigned32, Some("VL.KVFF")));
    assert_eq!((dtype(&m, 0x354B, 0), denotation(&m, 0x354B, 0)), (DataType::Integer32, Some("VL.KVFF")));
    assert_eq!((dtype(&m, 0x3412, 0), denotation(&m, 0x3412, 0)), (DataType::Integer8, Some("REGEN.TYPE")));
    assert_eq!((dtype(&m, 0x3450, 0), access(&m, 0x3450, 0)), (DataType::Unsigned8, Access::Wo));
    assert_eq!(m.object(0x3457).unwrap().object_type, ObjectType::Record);
    assert_eq!(dtype(&m, 0x3457, 1), DataType::Integer32);
    assert_eq!(dtype(&m, 0x3457, 2), DataType::Unsigned16);
    assert_eq!(denotation(&m, 0x3460, 0xA), Some("CAP1.PRESELECT"));
    assert_eq!((dtype(&m, 0x3470, 4), access(&m, 0x3470, 4)), (DataType::Integer16, Access::Ro));
    assert!(mappable(&m, 0x3470, 4));
    assert_eq!(dtype(&m, 0x3494, 1), DataType::Integer16);
    assert_eq!(denotation(&m, 0x34A0, 8), Some("PLS.P8"));
    assert_eq!(dtype(&m, 0x34A2, 1), DataType::Unsigned16);
    assert_eq!((dtype(&m, 0x35EB, 0), access(&m, 0x35EB, 0)), (DataType::Integer32, Access::Wo));
    assert_eq!(denotation(&m, 0x35EB, 0), Some("DRV.NVSAVE"));
    assert_eq!((dtype(&m, 0x3598, 0), denotation(&m, 0x3598, 0)), (DataType::Integer32, Some("IL.KP")));
    assert_eq!((dtype(&m, 0x3656, 0), denotation(&m, 0x3656, 0)), (DataType::Unsigned64, Some("FB1.ORIGIN")));
    assert_eq!(denotation(&m, 0x36E5, 0), Some("FBUS.PARAM01"));
    // 4.2 / 3.2.2: default baud rate 125 kbit/s
    assert_eq!(default_int(&m, 0x36E5, 0), 125);
    assert_eq!((dtype(&m, 0x36FC, 0), denotation(&m, 0x36FC, 0)), (DataType::Unsigned32, Some("DIN7.MODE")));
    assert_eq!((dtype(&m, 0x5268, 0), denotation(&m, 0x5268, 0)), (DataType::Unsigned32, Some("MOTOR.BRAKEIMM")));
    // decisions: ASCII typos corrected, 35AFh / 35B2h digital output modes, 525Ch fault 134
    assert_eq!(denotation(&m, 0x3426, 0), Some("IL.KACCFF"));
    assert_eq!(denotation(&m, 0x3533, 0), Some("FB1.ENCRES"));
    assert_eq!(denotation(&m, 0x35AF, 0), Some("DOUT1.MODE"));
    assert_eq!(denotation(&m, 0x35BC, 0), Some("MT.MTNEXT"));
    assert_eq!(denotation(&m, 0x525C, 0), Some("FAULT134.ACTION"));
    // decisions: blank access cells are rw, INTEGER is INTEGER32
    for i in [0x3422, 0x3423, 0x3424, 0x3506] {
        assert_eq!(access(&m, i, 0), Access::Rw, "0x{i:04X}");
    }
    assert_eq!(dtype(&m, 0x3506, 0), DataType::Integer32);
}

#[test]
fn device_control_and_modes_chapter_6_4() {
    let m = model();
    // 6.4.2.1: controlword UNSIGNED16, R/W (appendix WO; decision), mappable, default 0
    assert_eq!((dtype(&m, 0x6040, 0), access(&m, 0x6040, 0)), (DataType::Unsigned16, Access::Rw));
    assert!(mappable(&m, 0x6040, 0));
    assert_eq!(default_int(&m, 0x6040, 0), 0);
    // 6.4.2.2: statusword UNSIGNED16, ro (appendix; decision), mappable
    assert_eq!((dtype(&m, 0x6041, 0), access(&m, 0x6041, 0)), (DataType::Unsigned16, Access::Ro));
    // 6.4.2.3 / 6.4.2.4: modes of operation INTEGER8 rw / ro, mappable
    assert_eq!((dtype(&m, 0x6060, 0), access(&m, 0x6060, 0)), (DataType::Integer8, Access::Rw));
    assert_eq!((dtype(&m, 0x6061, 0), access(&m, 0x6061, 0)), (DataType::Integer8, Access::Ro));
    assert!(mappable(&m, 0x6060, 0) && mappable(&m, 0x6061, 0));
    // 6.2.3.10: supported drive modes 0x65 (ip hm pv pp)
    assert_eq!(default_int(&m, 0x6502, 0), 0x65);
    assert_eq!(default_int(&m, 0x6502, 0), (1 << 0) | (1 << 2) | (1 << 5) | (1 << 6));
    // 6.2.3.8 / 6.2.3.9: digital inputs ro mappable; outputs sub0 2, sub1 mappable, sub2 not
    assert_eq!((dtype(&m, 0x60FD, 0), access(&m, 0x60FD, 0)), (DataType::Unsigned32, Access::Ro));
    assert_eq!(default_int(&m, 0x60FE, 0), 2);
    assert!(mappable(&m, 0x60FE, 1) && !mappable(&m, 0x60FE, 2));
    // 6.2.3.1 to 6.2.3.7: touch probe
    assert_eq!((dtype(&m, 0x60B8, 0), access(&m, 0x60B8, 0)), (DataType::Unsigned16, Access::Rw));
    assert_eq!(access(&m, 0x60B9, 0), Access::Ro);
    for i in 0x60BA..=0x60BD {
        assert_eq!((dtype(&m, i, 0), access(&m, i, 0)), (DataType::Integer32, Access::Ro));
    }
    assert_eq!(default_int(&m, 0x60D0, 0), 2);
    for s in 1..=2 {
        assert_eq!((dtype(&m, 0x60D0, s), default_int(&m, 0x60D0, s)), (DataType::Integer16, 1));
        assert_eq!(limits(&m, 0x60D0, s), (Some(-11), Some(5)));
    }
}

#[test]
fn factor_group_and_motion_chapters_6_5_to_6_11() {
    let m = model();
    // 6.5.3.1: position encoder resolution 2^20 increments per 1 motor revolution
    assert_eq!(default_int(&m, 0x608F, 1), 1 << 20);
    assert_eq!(default_int(&m, 0x608F, 1), 1_048_576);
    assert_eq!(default_int(&m, 0x608F, 2), 1);
    // 6.5.3.2 / 6.5.3.3: gear ratio and feed constant 1/1; 6092h is UNIT.PIN / UNIT.POUT
    for i in [0x6091, 0x6092] {
        assert_eq!(default_int(&m, i, 0), 2);
        assert_eq!((default_int(&m, i, 1), default_int(&m, i, 2)), (1, 1));
        assert_eq!(dtype(&m, i, 1), DataType::Unsigned32);
    }
    assert_eq!(denotation(&m, 0x6092, 1), Some("UNIT.PIN"));
    assert_eq!(denotation(&m, 0x6092, 2), Some("UNIT.POUT"));
    // 6.6.2: velocity actual value / target velocity INTEGER32
    assert_eq!((dtype(&m, 0x606C, 0), denotation(&m, 0x606C, 0)), (DataType::Integer32, Some("VL.FB")));
    assert_eq!((dtype(&m, 0x60FF, 0), denotation(&m, 0x60FF, 0)), (DataType::Integer32, Some("VL.CMDU")));
    // 6.7.2.3 to 6.7.2.5: target torque INT16 rw, max current U16 not mappable, torque actual INT16 ro
    assert_eq!((dtype(&m, 0x6071, 0), access(&m, 0x6071, 0)), (DataType::Integer16, Access::Rw));
    assert_eq!(dtype(&m, 0x6073, 0), DataType::Unsigned16);
    assert!(!mappable(&m, 0x6073, 0));
    assert_eq!((dtype(&m, 0x6077, 0), access(&m, 0x6077, 0)), (DataType::Integer16, Access::Ro));
    // 6.8.2: 6063h / 6064h INTEGER32 mappable; 6065h U32 default 0; 60F4h INTEGER32
    assert_eq!(dtype(&m, 0x6063, 0), DataType::Integer32);
    assert_eq!(denotation(&m, 0x6064, 0), Some("PL.FB"));
    assert_eq!((dtype(&m, 0x6065, 0), default_int(&m, 0x6065, 0)), (DataType::Unsigned32, 0));
    assert_eq!(denotation(&m, 0x60F4, 0), Some("PL.ERR"));
    // 6.9.2.1: 60C0h INTEGER16, -2 / -1 / 0, default 0
    assert_eq!(dtype(&m, 0x60C0, 0), DataType::Integer16);
    assert_eq!(limits(&m, 0x60C0, 0), (Some(-2), Some(0)));
    // 6.9.2.2: 60C1h sub0 3; position INT32, time U32 (ms), velocity INT32; all mappable
    assert_eq!(default_int(&m, 0x60C1, 0), 3);
    assert_eq!(dtype(&m, 0x60C1, 1), DataType::Integer32);
    assert_eq!(dtype(&m, 0x60C1, 2), DataType::Unsigned32);
    assert_eq!(dtype(&m, 0x60C1, 3), DataType::Integer32);
    assert!((1..=3).all(|s| mappable(&m, 0x60C1, s)));
    // 6.9.2.3: 60C2h sub1 U8 default 1, sub2 INTEGER16
    assert_eq!((dtype(&m, 0x60C2, 1), default_int(&m, 0x60C2, 1)), (DataType::Unsigned8, 1));
    assert_eq!(dtype(&m, 0x60C2, 2), DataType::Integer16);
    // 6.9.2.4: 60C4h sub0 6, max buffer 10, actual 9 (0 to 9), record size 1 (1 to 254)
    assert_eq!(default_int(&m, 0x60C4, 0), 6);
    assert_eq!(default_int(&m, 0x60C4, 1), 10);
    assert_eq!(default_int(&m, 0x60C4, 2), 9);
    assert_eq!(limits(&m, 0x60C4, 2), (Some(0), Some(9)));
    assert_eq!(default_int(&m, 0x60C4, 5), 1);
    assert_eq!(limits(&m, 0x60C4, 5), (Some(1), Some(254)));
    assert_eq!(access(&m, 0x60C4, 6), Access::Wo);
    // 6.10.2: home offset INT32 0, method INT8 0, speeds U32, acceleration U32 0
    assert_eq!((dtype(&m, 0x607C, 0), default_int(&m, 0x607C, 0)), (DataType::Integer32, 0));
    assert_eq!((dtype(&m, 0x6098, 0), default_int(&m, 0x6098, 0)), (DataType::Integer8, 0));
    assert_eq!(denotation(&m, 0x6098, 0), Some("HOME.MODE, HOME.DIR"));
    assert_eq!(denotation(&m, 0x6099, 1), Some("HOME.V"));
    assert_eq!(denotation(&m, 0x6099, 2), Some("HOME.FEEDRATE"));
    assert_eq!((dtype(&m, 0x609A, 0), default_int(&m, 0x609A, 0)), (DataType::Unsigned32, 0));
    // 6.11.2.1: target position range -(2^31-1) .. 2^31-1
    assert_eq!(limits(&m, 0x607A, 0), (Some(-(i32::MAX as i128)), Some(i32::MAX as i128)));
    assert_eq!(denotation(&m, 0x607A, 0), Some("MT.P"));
    // 6.11.2.2: software limits, default 0 (disabled)
    assert_eq!(denotation(&m, 0x607D, 1), Some("SWLS.LIMIT0"));
    assert_eq!((default_int(&m, 0x607D, 1), default_int(&m, 0x607D, 2)), (0, 0));
    // 6.11.2.3 to 6.11.2.5: profile velocity default 10, acceleration / deceleration 0
    assert_eq!(default_int(&m, 0x6081, 0), 10);
    assert_eq!((default_int(&m, 0x6083, 0), default_int(&m, 0x6084, 0)), (0, 0));
    assert_eq!(denotation(&m, 0x6084, 0), Some("MT.DEC"));
}

#[test]
fn device_info_chapters_3_and_4() {
    let m = model();
    let d = &m.device_info;
    // 3.2.2 / 4.2: 125 (default), 250, 500, 1000 kbit/s
    for (rate, on) in [(10u16, false), (20, false), (50, false), (125, true), (250, true), (500, true), (800, false)] {
        assert_eq!(d.baud_rates.get(&rate), Some(&on), "{rate} kbit/s");
    }
    assert_eq!(d.baud_rates.get(&1000), Some(&true));
    // 5.4.6: four PDO channels per direction
    assert_eq!((d.nr_of_rx_pdo, d.nr_of_tx_pdo), (Some(4), Some(4)));
    assert_eq!(d.simple_boot_up_slave, Some(true));
    assert_eq!(d.vendor_number, Some(0x6A));
    assert_eq!(d.product_number, Some(u32::from_le_bytes(*b"M006")));
    assert_eq!(d.revision_number, Some(0x0014_0000));
    // 6.3.1.2: mappings in whole bytes
    assert_eq!(d.granularity, Some(8));
    assert!(m.comments.len() >= 50);
}

/// One expedited SDO download: `(cob_id, [cmd, idx_lo, idx_hi, sub, d0, d1, d2, d3])`.
type Frame = (u16, [u8; 8]);

/// Chapter 7.2 frame listings: each SDO download whose command byte is consistent must fit
/// the dictionary (size of the data type, writable, value in range). The full
/// request/response exchanges are the simulated drive's acceptance tests; typos are listed in
/// `chapter_7_2_typos_are_recognised`.
#[test]
fn chapter_7_2_sdo_downloads_fit_the_dictionary() {
    let m = model();
    let frames: &[Frame] = &[
        // 7.2.1.2 state machine (node 3)
        (0x603, [0x2B, 0x40, 0x60, 0x00, 0x06, 0x00, 0x00, 0x00]),
        (0x603, [0x2B, 0x40, 0x60, 0x00, 0x07, 0x00, 0x00, 0x00]),
        // 7.2.1.3 profile velocity by SDO
        (0x603, [0x2F, 0x60, 0x60, 0x00, 0x03, 0x00, 0x00, 0x00]),
        (0x603, [0x23, 0xFF, 0x60, 0x00, 0x00, 0x41, 0x00, 0x00]),
        (0x603, [0x2B, 0x40, 0x60, 0x00, 0x0F, 0x01, 0x00, 0x00]),
        // 7.2.1.4 torque by SDO
        (0x603, [0x2F, 0x60, 0x60, 0x00, 0x04, 0x00, 0x00, 0x00]),
        (0x603, [0x2B, 0x71, 0x60, 0x00, 0x90, 0x01, 0x00, 0x00]),
        // 7.2.1.5 velocity by PDO: remapping and disabling PDOs
        (0x603, [0x2F, 0x00, 0x16, 0x00, 0x00, 0x00, 0x00, 0x00]),
        (0x603, [0x23, 0x00, 0x16, 0x01, 0x20, 0x00, 0xFF, 0x60]),
        (0x603, [0x2F, 0x00, 0x16, 0x00, 0x01, 0x00, 0x00, 0x00]),
        (0x603, [0x23, 0x00, 0x1A, 0x01, 0x20, 0x00, 0x64, 0x60]),
        (0x603, [0x23, 0x00, 0x1A, 0x02, 0x20, 0x00, 0x6C, 0x60]),
        (0x603, [0x2F, 0x00, 0x1A, 0x00, 0x02, 0x00, 0x00, 0x00]),
        (0x603, [0x2F, 0x00, 0x18, 0x02, 0x01, 0x00, 0x00, 0x00]),
        (0x603, [0x23, 0x01, 0x18, 0x01, 0x83, 0x02, 0x00, 0x80]),
        (0x603, [0x23, 0x01, 0x14, 0x01, 0x03, 0x03, 0x00, 0x80]),
        // 7.2.1.6 torque by PDO
        (0x603, [0x23, 0x00, 0x16, 0x01, 0x10, 0x00, 0x71, 0x60]),
        (0x603, [0x23, 0x00, 0x1A, 0x01, 0x10, 0x00, 0x77, 0x60]),
        // 7.2.1.7 homing by SDO
        (0x603, [0x23, 0x99, 0x60, 0x01, 0x10, 0x27, 0x00, 0x00]),
        (0x603, [0x23, 0x99, 0x60, 0x02, 0x88, 0x13, 0x00, 0x00]),
        (0x603, [0x23, 0x9A, 0x60, 0x00, 0x10, 0x27, 0x00, 0x00]),
        (0x603, [0x23, 0x7C, 0x60, 0x00, 0xA8, 0x61, 0x00, 0x00]),
        (0x603, [0x2F, 0x60, 0x60, 0x00, 0x06, 0x00, 0x00, 0x00]),
        (0x603, [0x2B, 0x40, 0x60, 0x00, 0x1F, 0x00, 0x00, 0x00]),
        // 7.2.1.8 profile position
        (0x603, [0x23, 0x01, 0x16, 0x01, 0x20, 0x00, 0x7A, 0x60]),
        (0x603, [0x23, 0x01, 0x16, 0x02, 0x20, 0x00, 0x81, 0x60]),
        (0x603, [0x2F, 0x98, 0x60, 0x00, 0x0C, 0x00, 0x00, 0x00]),
        (0x603, [0x2F, 0x60, 0x60, 0x00, 0x01, 0x00, 0x00, 0x00]),
        (0x603, [0x23, 0x83, 0x60, 0x00, 0x32, 0x00, 0x00, 0x00]),
        (0x603, [0x23, 0x84, 0x60, 0x00, 0x32, 0x00, 0x00, 0x00]),
        // 7.2.1.9 ASCII channel (node 1): "DRV." "FAUL" "TS\r\n"
        (0x601, [0x23, 0x26, 0x20, 0x01, b'D', b'R', b'V', b'.']),
        (0x601, [0x23, 0x26, 0x20, 0x01, b'T', b'S', 0x0D, 0x0A]),
        // 7.2.1.10 SYNC test
        (0x603, [0x2F, 0x00, 0x18, 0x02, 0x02, 0x00, 0x00, 0x00]),
        (0x603, [0x23, 0x01, 0x1A, 0x02, 0x20, 0x00, 0x02, 0x10]),
        (0x603, [0x2F, 0x01, 0x18, 0x02, 0x03, 0x00, 0x00, 0x00]),
        // 7.2.2.1 interpolated position, two axes (nodes 1 and 2)
        (0x601, [0x23, 0x01, 0x16, 0x01, 0x20, 0x01, 0xC1, 0x60]),
        (0x601, [0x23, 0x01, 0x16, 0x02, 0x20, 0x00, 0x00, 0x21]),
        (0x601, [0x23, 0x01, 0x1A, 0x01, 0x20, 0x00, 0x63, 0x60]),
        (0x601, [0x2F, 0x01, 0x14, 0x02, 0x01, 0x00, 0x00, 0x00]),
        (0x601, [0x23, 0x02, 0x18, 0x01, 0x81, 0x03, 0x00, 0x80]),
        (0x601, [0x2F, 0x60, 0x60, 0x00, 0x07, 0x00, 0x00, 0x00]),
        (0x601, [0x2F, 0xC2, 0x60, 0x01, 0x01, 0x00, 0x00, 0x00]),
        // 7.2.2.2 PVT
        (0x601, [0x23, 0x01, 0x14, 0x01, 0x01, 0x03, 0x00, 0x80]),
        (0x601, [0x23, 0x01, 0x16, 0x02, 0x20, 0x02, 0xC1, 0x60]),
        (0x601, [0x23, 0x02, 0x16, 0x01, 0x20, 0x03, 0xC1, 0x60]),
        // 6.3: TPDO1 remapping example (node 1)
        (0x601, [0x23, 0x00, 0x18, 0x01, 0x81, 0x01, 0x00, 0xC0]),
        (0x601, [0x23, 0x00, 0x1A, 0x01, 0x10, 0x00, 0x41, 0x60]),
    ];
    for (cob, f) in frames {
        let node = (cob - 0x600) as u8;
        let index = u16::from_le_bytes([f[1], f[2]]);
        let e = m.entry(index, f[3]).unwrap_or_else(|| panic!("7.2 writes 0x{index:04X} sub {}", f[3]));
        assert_eq!(f[0] & 0xE3, 0x23, "expedited download with size indicated");
        let bytes = 4 - ((f[0] >> 2) & 0x3) as u32;
        assert!(e.access.writable(), "0x{index:04X} sub {}", f[3]);
        let raw = u32::from_le_bytes([f[4], f[5], f[6], f[7]]) & (u32::MAX >> (32 - 8 * bytes));
        match e.data_type.bits() {
            Some(bits) => {
                assert_eq!(bits, bytes * 8, "0x{index:04X} sub {}", f[3]);
                let (lo, hi) = e.data_type.int_range().unwrap();
                let value = if e.data_type.is_signed() {
                    (((raw as u64) << (64 - bits)) as i64 >> (64 - bits)) as i128
                } else {
                    raw as i128
                };
                assert!((lo..=hi).contains(&value));
            }
            None => assert_eq!(e.data_type, DataType::VisibleString),
        }
        // mapping entries must name mappable objects of the right size
        if ((0x1600..=0x1603).contains(&index) || (0x1A00..=0x1A03).contains(&index)) && f[3] > 0 {
            let p = PdoMappingEntry::from_u32(raw);
            let t = m.entry(p.index.0, p.sub.0).unwrap_or_else(|| panic!("maps missing {p:?}"));
            assert!(t.pdo_mapping, "{p:?}");
            assert_eq!(t.data_type.bits(), Some(p.bits as u32), "{p:?}");
        }
        // a COB-ID written to disable a PDO is its default with bit 31 (and bit 30) set
        if f[3] == 1 && ((0x1400..=0x1403).contains(&index) || (0x1800..=0x1803).contains(&index)) {
            let cob_default = e.default.as_ref().unwrap().resolve(node).unwrap() as u32;
            assert_eq!(raw & 0x7FF, cob_default, "0x{index:04X} node {node}");
            assert_ne!(raw & 0x8000_0000, 0, "0x{index:04X}: bit 31 (PDO not valid)");
        }
    }
    // 7.2.1.4: setpoint 0x0190 = 400; 7.2.1.7: 0x2710 = 10000, 0x1388 = 5000, 0x61A8 = 25000
    assert_eq!((0x0190, 0x2710, 0x1388, 0x61A8), (400, 10_000, 5_000, 25_000));
    // 7.2.2.1: 60C2h sub2 FD = -3 -> period 1 * 10^-3 s
    assert_eq!(0xFDu8 as i8, -3);
    assert_eq!(default_int(&m, 0x60C2, 2), -3);
}

/// The typos of chapter 7.2 recorded in the sidecar decisions, asserted so that a later
/// acceptance test does not take them literally.
#[test]
fn chapter_7_2_typos_are_recognised() {
    let m = model();
    // 7.2.1.8 writes 6093h (not in this dictionary)
    assert!(m.object(0x6093).is_none());
    // 7.2.2.2 writes 608Fh sub1 with 0x2B (2 bytes) but it is 32 bits
    assert_eq!(dtype(&m, 0x608F, 1).bits(), Some(32));
    // 7.2.2.2 writes 1401h sub2 with 0x23 (4 bytes) but the transmission type is 8 bits
    assert_eq!(dtype(&m, 0x1401, 2).bits(), Some(8));
    // 7.2.2.2 disables TPDO1 with 0x80000281: TPDO1 of node 1 is 0x181
    assert_eq!(entry(&m, 0x1800, 1).default.as_ref().unwrap().resolve(1), Some(0x181));
    // 7.2.2.2 "00 00 FE FF": -2 written little-endian is FE FF
    assert_eq!((-2i16).to_le_bytes(), [0xFE, 0xFF]);
    // 7.2.1.9: "ctiv" is 63 74 69 76, the listing prints 63 64 69 76
    assert_eq!(*b"ctiv", [0x63, 0x74, 0x69, 0x76]);
    // 7.2.1.8: abort 0x06090031 (value too high) as printed in the 6099h response
    assert_eq!(u32::from_le_bytes([0x31, 0x00, 0x09, 0x06]), 0x0609_0031);
    let s = sidecar();
    for needle in ["7.2.1.5", "7.2.1.7", "7.2.1.8", "7.2.1.9", "7.2.1.10", "7.2.2.1", "7.2.2.2"] {
        assert!(s.decisions.iter().any(|d| d.source.as_deref().unwrap_or("").contains(needle)), "{needle}");
    }
}

#[test]
fn loads_without_errors_in_strict_mode() {
    let parsed = load_with(&Options::strict());
    let errors: Vec<_> = parsed.errors().collect();
    assert!(errors.is_empty(), "strict errors: {errors:#?}");
}

#[test]
fn index_is_ordered_and_names_are_english() {
    let m = model();
    for (o, e) in m.entries() {
        assert!(!e.name.is_empty() && e.name.is_ascii(), "0x{:04X} sub {}", o.index.0, e.sub.0);
        for word in ["Numero", "Registro", "Posizione", "Impostazione", "Valore", "Tipo di"] {
            assert!(!e.name.contains(word), "Italian name at 0x{:04X} sub {}: {}", o.index.0, e.sub.0, e.name);
        }
    }
    // object names are unique (one generated identifier each)
    let mut names: Vec<&str> = m.objects.values().map(|o| o.name.as_str()).collect();
    names.sort();
    let n = names.len();
    names.dedup();
    assert_eq!(names.len(), n, "duplicate object names");
}

// ---------------------------------------------------------------------------------------------
// The sidecar (devices/kollmorgen-akd.toml)
// ---------------------------------------------------------------------------------------------

fn sidecar() -> Sidecar {
    Sidecar::read(&devices::sidecar_path("kollmorgen-akd")).unwrap_or_else(|e| panic!("{e}"))
}

fn r(s: &str) -> ObjRef {
    s.parse().unwrap()
}

/// 6.3.1.2 and the listings 7.2.1.5 to 7.2.2.1: the AKD remaps a PDO that stays valid; the
/// Camozzi manuals give CiA 301's sequence (DRVI 6.3.2.20, DRCS 3.2.22: bit 31 first) and keep
/// the default.
#[test]
fn pdo_remapping_rule_of_each_device() {
    assert_eq!(sidecar().pdo.remapping, Remapping::WhileValid);
    assert!(sidecar().pdo.source.unwrap().contains("6.3.1.2"));
    for name in ["camozzi-drvi", "camozzi-drcs"] {
        let s = Sidecar::read(&devices::sidecar_path(name)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(s.pdo.remapping, Remapping::Cia301, "{name}");
    }
}

#[test]
fn sidecar_parses() {
    let s = sidecar();
    assert_eq!(s.device.name, "kollmorgen-akd");
    assert_eq!(s.device.eds, "kollmorgen-akd.eds");
    assert_eq!(s.device.manual.as_deref(), Some("kollmorgen-akd-canbus-manual-it.txt"));
}

#[test]
fn sidecar_refers_only_to_existing_entries() {
    let s = sidecar();
    let m = model();
    for (r, what) in s.references() {
        let o = m.object(r.index).unwrap_or_else(|| panic!("{what} refers to missing {r}"));
        if let Some(sub) = r.sub {
            assert!(o.sub(sub).is_some(), "{what} refers to missing {r}");
        }
    }
}

#[test]
fn bus_scaling_appendix_7_1() {
    let s = sidecar();
    // 7.1.1: 607Ah is 1:1 (SDO 1000 = MT.P 1000.000), 3598h is 1000:1 (SDO 1000 = IL.KP 1.000)
    assert_eq!(s.bus_scaling[&r("0x607A")], BusScaling::Factor(1));
    assert_eq!(s.bus_scaling[&r("0x3598")], BusScaling::Factor(1000));
    // 7.1.4: 606Ch 1000:1, 6064h 1:1, 6099h sub1 1:1 (sub2 blank)
    assert_eq!(s.bus_scaling[&r("0x606C")], BusScaling::Factor(1000));
    assert_eq!(s.bus_scaling[&r("0x6064")], BusScaling::Factor(1));
    assert_eq!(s.bus_scaling[&r("0x6099sub1")], BusScaling::Factor(1));
    assert!(!s.bus_scaling.contains_key(&r("0x6099sub2")));
    // 7.1.3: latch positions var; 3406h subs 1000:1; 3440h sub3 blank
    for i in ["0x20A0", "0x20A1", "0x20A2", "0x20A3", "0x20A6"] {
        assert_eq!(s.bus_scaling[&r(i)], BusScaling::Variable, "{i}");
    }
    for sub in 1..=16 {
        assert_eq!(s.bus_scaling[&ObjRef { index: 0x3406, sub: Some(sub) }], BusScaling::Factor(1000));
    }
    assert_eq!(s.bus_scaling[&r("0x3440sub1")], BusScaling::Factor(1));
    assert!(!s.bus_scaling.contains_key(&r("0x3440sub3")));
    assert!(!s.bus_scaling.contains_key(&r("0x6040")));
    // 7.1.1: bus value = WorkBench value * factor
    let to_bus = |wb: f64, f: &BusScaling| match f {
        BusScaling::Factor(k) => wb * *k as f64,
        BusScaling::Variable => f64::NAN,
    };
    assert_eq!(to_bus(1.0, &s.bus_scaling[&r("0x3598")]), 1000.0);
    assert_eq!(to_bus(1000.0, &s.bus_scaling[&r("0x607A")]), 1000.0);
    assert_eq!(s.bus_scaling.len(), 121);
}

/// `position_inc = position_user * (608Fh.1/608Fh.2) * (6091h.1/6091h.2) / (6092h.1/6092h.2)`
fn position_inc(user: f64, enc: (f64, f64), gear: (f64, f64), feed: (f64, f64)) -> f64 {
    user * (enc.0 / enc.1) * (gear.0 / gear.1) / (feed.0 / feed.1)
}

#[test]
fn units_and_scaling_chapter_6_5() {
    let s = sidecar();
    let m = model();
    // 6.5: FBUS.PARAM05 bit 4 = 1 selects the DS402 factors
    let ds402 = s.active_unit_system(|o| (o.index == 0x36E9).then_some(0x10)).unwrap();
    assert_eq!(ds402.name, "ds402-factors");
    // other bits of FBUS.PARAM05 do not matter, only bit 4 does
    assert_eq!(s.active_unit_system(|o| (o.index == 0x36E9).then_some(0x13)).unwrap().name, "ds402-factors");
    assert_eq!(s.active_unit_system(|o| (o.index == 0x36E9).then_some(0x0F)).unwrap().name, "workbench-units");
    assert_eq!(
        ds402.units[&Dimension::Position].scaled_by,
        vec![ScalingKind::EncoderResolution, ScalingKind::GearRatio, ScalingKind::FeedConstant]
    );
    assert!(ds402.units[&Dimension::Velocity].scaled_by.contains(&ScalingKind::VelocityFactor));
    let wb = s.active_unit_system(|_| Some(0)).unwrap();
    assert_eq!(wb.name, "workbench-units");
    for u in [ds402, wb] {
        assert_eq!(u.units[&Dimension::Position].unit, Unit::UserUnit);
        assert_eq!(u.units[&Dimension::Velocity].unit, Unit::UserUnitPerSecond);
        assert_eq!(u.units[&Dimension::Acceleration].unit, Unit::UserUnitPerSecond2);
        // 6.7.2.3: per mille of rated torque; 6.7.2.1: mA
        assert_eq!(u.units[&Dimension::Torque].unit, Unit::PermilleRatedTorque);
        assert_eq!(u.units[&Dimension::Current].unit, Unit::MilliAmpere);
        // 6.9.2.2: interpolation time in ms
        assert_eq!(u.units[&Dimension::Time].unit, Unit::Millisecond);
    }
    // scaling objects and their sub-index roles
    let enc = s.scaling_object(ScalingKind::EncoderResolution).unwrap();
    assert_eq!((enc.object.index, enc.subs["encoder_increments"], enc.subs["motor_revolutions"]), (0x608F, 1, 2));
    let gear = s.scaling_object(ScalingKind::GearRatio).unwrap();
    assert_eq!((gear.object.index, gear.subs["motor_revolutions"], gear.subs["shaft_revolutions"]), (0x6091, 1, 2));
    let feed = s.scaling_object(ScalingKind::FeedConstant).unwrap();
    assert_eq!((feed.object.index, feed.subs["feed"], feed.subs["shaft_revolutions"]), (0x6092, 1, 2));
    let pv = s.scaling_object(ScalingKind::VelocityFactor).unwrap();
    assert_eq!((pv.object.index, pv.subs["numerator"], pv.subs["denominator"]), (0x204C, 1, 2));
    assert!(pv.formula.contains("numerator / denominator"));
    // with the defaults (2^20/1, 1/1, 1/1) one user unit is one motor turn of 2^20 increments
    let d = |i, s| default_int(&m, i, s) as f64;
    let defaults = ((d(0x608F, 1), d(0x608F, 2)), (d(0x6091, 1), d(0x6091, 2)), (d(0x6092, 1), d(0x6092, 2)));
    assert_eq!(position_inc(1.0, defaults.0, defaults.1, defaults.2), 1_048_576.0);
    // 7.2.1.8: 2^20 increments for 36000 user units (0.01 deg): a feed of 36000 per turn
    assert_eq!(position_inc(36_000.0, (1_048_576.0, 1.0), (1.0, 1.0), (36_000.0, 1.0)), 1_048_576.0);
    assert_eq!(position_inc(9_000.0, (1_048_576.0, 1.0), (1.0, 1.0), (36_000.0, 1.0)), 262_144.0);
    // a 10:1 gearbox needs ten motor turns per driving-shaft turn
    assert_eq!(position_inc(36_000.0, (1_048_576.0, 1.0), (10.0, 1.0), (36_000.0, 1.0)), 10_485_760.0);
}

#[test]
fn dimensions_of_motion_objects() {
    let s = sidecar();
    for i in [0x6064, 0x6065, 0x607A, 0x607C, 0x60F4, 0x60BA] {
        assert_eq!(s.dimension_of(i, 0), Some(Dimension::Position), "0x{i:04X}");
    }
    assert_eq!(s.dimension_of(0x607D, 1), Some(Dimension::Position));
    for i in [0x606B, 0x606C, 0x60FF, 0x6081, 0x60B1] {
        assert_eq!(s.dimension_of(i, 0), Some(Dimension::Velocity), "0x{i:04X}");
    }
    assert_eq!(s.dimension_of(0x6099, 2), Some(Dimension::Velocity));
    for i in [0x6083, 0x6084, 0x609A] {
        assert_eq!(s.dimension_of(i, 0), Some(Dimension::Acceleration), "0x{i:04X}");
    }
    for i in [0x6071, 0x6077] {
        assert_eq!(s.dimension_of(i, 0), Some(Dimension::Torque), "0x{i:04X}");
    }
    for i in [0x2071, 0x2077] {
        assert_eq!(s.dimension_of(i, 0), Some(Dimension::Current), "0x{i:04X}");
    }
    assert_eq!(s.dimension_of(0x60C1, 2), Some(Dimension::Time));
    // increments, counts and per mille of rated current: deliberately without a dimension
    assert_eq!(s.dimension_of(0x6063, 0), None);
    assert_eq!(s.dimension_of(0x60C1, 1), None);
    assert_eq!(s.dimension_of(0x6073, 0), None);
}

#[test]
fn modes_and_homing_chapters_6_4_and_6_10() {
    let s = sidecar();
    // 6.4.2.3: 1, 3, 4, 6, 7, 8
    let codes: Vec<i8> = s.modes.iter().map(|m| m.code).collect();
    assert_eq!(codes, vec![1, 3, 4, 6, 7, 8]);
    let ip = s.modes.iter().find(|m| m.code == 7).unwrap();
    for obj in ["60C0h", "60C1h", "60C2h"] {
        assert!(ip.note.as_deref().unwrap().contains(obj), "{obj}");
    }
    // 6.10.2.2: supported homing methods
    let h: Vec<i8> = s.homing_methods.iter().map(|h| h.code).collect();
    assert_eq!(h, vec![1, 2, 8, 12, 17, 18, 24, 28, 33, 34, 35]);
    let desc = |c: i8| s.homing_methods.iter().find(|h| h.code == c).unwrap().description.as_str();
    assert!(desc(17).contains("HOME.MODE 1, HOME.DIR 0"));
    assert!(desc(18).starts_with("Positive limit switch"));
    assert!(desc(35).contains("current position"));
    // 7.2.1.8 uses method 12 (0x0C): reference switch, negative direction
    assert!(desc(12).contains("negative"));
}

#[test]
fn emergency_codes_chapter_6_1() {
    let s = sidecar();
    // The 171 rows of 6.1 and the hardware limit switch warning (CiA 402 8612h, see the
    // decision on 60FDh), which has no vendor code.
    assert_eq!(s.errors.len(), 172);
    let find = |code: i64| s.errors.iter().find(|e| e.code.0 == code).unwrap_or_else(|| panic!("0x{code:04X}"));
    assert_eq!((find(0x8612).vendor_code.as_deref(), find(0x8612).reaction), (None, Reaction::Warning));
    // 6.1 rows
    assert_eq!(find(0x0000).reaction, Reaction::None);
    assert_eq!((find(0x3110).vendor_code.as_deref(), find(0x3110).text.as_str()), (Some("F523"), "Bus over voltage"));
    assert_eq!(find(0x3110).reaction, Reaction::QuickStop);
    assert_eq!(
        (find(0x3180).vendor_code.as_deref(), find(0x3180).text.as_str()),
        (Some("n503"), "Warning: Supply missing phase")
    );
    assert_eq!(find(0x3180).reaction, Reaction::Warning);
    assert_eq!(
        (find(0x4310).vendor_code.as_deref(), find(0x4310).text.as_str()),
        (Some("F235"), "Excess temperature, drive (heat sink)")
    );
    assert_eq!(
        (find(0x8130).vendor_code.as_deref(), find(0x8130).text.as_str()),
        (Some("F129"), "Life Guard Error or Heartbeat Error")
    );
    assert_eq!((find(0x8611).vendor_code.as_deref(), find(0x8611).text.as_str()), (Some("F439"), "Following error"));
    assert_eq!(
        (find(0xFF01).vendor_code.as_deref(), find(0xFF01).text.as_str()),
        (Some("F702"), "Fieldbus communication lost")
    );
    // 4.3: BUSOFF disables the power stage
    assert_eq!(find(0xFF01).reaction, Reaction::PowerOff);
    assert_eq!(find(0xFF0B).reaction, Reaction::PowerOff);
    assert_eq!(find(0x1080).text, "General warning");
    assert_eq!(find(0x1081).text, "General error");
    // every warning (nnnn) is a warning, every fault (Fnnn) is not
    for e in &s.errors {
        let vendor = e.vendor_code.as_deref().unwrap_or("");
        if vendor.starts_with('n') {
            assert_eq!(e.reaction, Reaction::Warning, "{}", e.text);
        }
        if vendor.starts_with('F') {
            assert!(matches!(e.reaction, Reaction::QuickStop | Reaction::PowerOff), "{}", e.text);
        }
    }
    // codes are unique
    let mut codes: Vec<i64> = s.errors.iter().map(|e| e.code.0).collect();
    codes.sort();
    codes.dedup();
    assert_eq!(codes.len(), s.errors.len());
}

#[test]
fn store_section_6_2_1_12() {
    let s = sidecar();
    let m = model();
    // 3.2.2: the baud rate is stored by 1010h sub1; 6.11.2.2: software limits must be saved
    assert!(s.store.objects.contains(&r("0x36E5")));
    assert!(s.store.objects.contains(&r("0x607D")));
    assert!(!s.store.objects.contains(&r("0x6040")));
    for o in &s.store.objects {
        let obj = m.object(o.index).unwrap_or_else(|| panic!("{o}"));
        let writable = match o.sub {
            Some(sub) => obj.sub(sub).unwrap().access.writable(),
            None => obj.subs.values().any(|e| e.access.writable()),
        };
        assert!(writable, "{o}");
    }
}

#[test]
fn every_eds_comment_is_a_sidecar_decision() {
    let s = sidecar();
    let m = model();
    assert!(s.decisions.len() >= m.comments.len());
    for c in &m.comments {
        assert!(s.decisions.iter().any(|d| &d.text == c), "EDS comment without sidecar decision: {c}");
    }
    for needle in ["6.2.1.17", "M006", "35AFh", "2100h", "60C0h", "6063h"] {
        assert!(m.comments.iter().any(|c| c.contains(needle)), "EDS comments lack {needle}");
    }
}
