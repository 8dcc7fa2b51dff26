use super::*;
use eds::model::{Access, DataType as D, Model, ObjectType, Radix, Value};

/// A small deterministic generator (SplitMix64), so a failing seed reproduces.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }
    fn chance(&mut self, percent: usize) -> bool {
        self.below(100) < percent
    }
}

const NAMES: &[&str] = &[
    "Speed",
    "speed",
    "Set speed",
    "Point",
    "Set point",
    "type",
    "new",
    "read",
    "1st receive PDO parameter",
    "2nd",
    "COB-IDs",
    "Übergröße °C",
    "",
    " -- ",
    "Error history",
    "Error history 1",
    "Mapped object",
    "Highest sub-index supported",
    "Self",
    "self",
    "a very long parameter name that goes on with many words describing the maximum value of something",
    "Input interrupt mask low-to-high for digital inputs 1-32",
    "RPDO mapping parameter",
    "Trace",
    "x",
    "set_",
    "Über",
    "1. Receive PDO parameter",
    "1rst receive PDO communication parameter",
    "3) Mode",
    "5V DC supply",
    "8-Bit analog Input 1",
    "2eme",
    "CANopen baudrate",
    "EtherCAT IOs",
];

const TYPES: &[D] = &[
    D::Boolean,
    D::Integer8,
    D::Integer16,
    D::Integer24,
    D::Integer32,
    D::Integer40,
    D::Integer64,
    D::Unsigned8,
    D::Unsigned16,
    D::Unsigned24,
    D::Unsigned32,
    D::Unsigned48,
    D::Unsigned64,
    D::Real32,
    D::Real64,
    D::VisibleString,
    D::OctetString,
    D::UnicodeString,
    D::Domain,
    D::TimeOfDay,
    D::Other(0x0020),
];

const ACCESS: &[Access] = &[Access::Ro, Access::Wo, Access::Rw, Access::Rwr, Access::Rww, Access::Const];

const INTS: &[i128] = &[
    0,
    1,
    -1,
    127,
    128,
    255,
    256,
    -129,
    65535,
    0x8000_0000,
    -0x8000_0000,
    0xFFFF_FFFF,
    1 << 40,
    i64::MAX as i128,
    u64::MAX as i128,
    i64::MIN as i128,
];

fn value(r: &mut Rng) -> Option<Value> {
    Some(match r.below(9) {
        0 => return None,
        1..=3 => Value::Int { value: *r.pick(INTS), radix: if r.chance(50) { Radix::Hex } else { Radix::Dec } },
        4 => Value::NodeIdPlus { offset: *r.pick(&[0, 0x180, -1, 0x7FFF_FFFF, -200]), radix: Radix::Hex },
        5 => Value::Real(*r.pick(&[0.5, -2.25, 1e300, -1e300, f64::NAN, f64::INFINITY, 3.4e38, 1e-300])),
        6 => Value::Text(r.pick(&["", "abc", "Ünïcode \"quoted\" #", "a\nb"]).to_string()),
        7 => Value::Bytes(vec![0xAB; r.below(40)]),
        _ => Value::Int { value: r.below(3) as i128, radix: Radix::Dec },
    })
}

fn entry_at(r: &mut Rng, sub: u8, name: &str) -> eds::model::Entry {
    let mut e = entry(sub, name, *r.pick(TYPES), *r.pick(ACCESS), value(r), r.chance(50));
    if r.chance(30) {
        e.extras_mut().low_limit = value(r);
    }
    if r.chance(30) {
        e.extras_mut().high_limit = value(r);
    }
    if r.chance(10) {
        e.extras_mut().parameter_value = value(r);
    }
    e
}

pub fn model(seed: u64) -> Model {
    let mut r = Rng(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0x5EED);
    let mut objects = Vec::new();
    let mut used = std::collections::BTreeSet::new();
    let n = 3 + r.below(30);
    let mut indexes = Vec::new();
    for _ in 0..n {
        let index = match r.below(4) {
            0 => 0x1000 + r.below(0x20) as u16,
            1 => 0x2000 + r.below(0x40) as u16,
            2 => 0x6000 + r.below(0x80) as u16,
            _ => 0x1400 + r.below(4) as u16 * 0x200 + r.below(3) as u16,
        };
        if !used.insert(index) {
            continue;
        }
        let name = *r.pick(NAMES);
        let obj = match r.below(3) {
            0 => {
                let mut o = object(index, name, ObjectType::Var, vec![entry_at(&mut r, 0, name)]);
                o.subs.values_mut().for_each(|e| e.name = name.into());
                o
            }
            kind => {
                let subs = 1 + r.below(6);
                let mut entries = vec![entry(
                    0,
                    "Highest sub-index supported",
                    D::Unsigned8,
                    Access::Ro,
                    Some(Value::int(subs as i128)),
                    false,
                )];
                for s in 1..=subs {
                    let sub_name = if r.chance(40) { name.to_owned() } else { r.pick(NAMES).to_string() };
                    entries.push(entry_at(&mut r, s as u8, &sub_name));
                }
                object(index, name, if kind == 1 { ObjectType::Array } else { ObjectType::Record }, entries)
            }
        };
        indexes.push(index);
        objects.push(obj);
    }
    // Default PDO mappings of present, absent and dummy entries, placeholders, wrong lengths.
    for map_index in [0x1600u16, 0x1601, 0x1A00, 0x1A01] {
        if used.contains(&map_index) || !r.chance(60) {
            continue;
        }
        let count = r.below(5);
        let raw: Vec<u32> = (0..count)
            .map(|_| match r.below(5) {
                0 => 0,
                1 => 0x0005_0008,
                _ => {
                    let i = if indexes.is_empty() { 0x7000 } else { *r.pick(&indexes) };
                    let sub = r.below(3) as u32;
                    let bits = *r.pick(&[1u32, 8, 16, 28, 32, 64]);
                    (i as u32) << 16 | sub << 8 | bits
                }
            })
            .collect();
        let mut m = mapping(map_index, &raw);
        if r.chance(20) {
            // sub 0 counts more entries than there are.
            if let Some(e) = m.subs.values_mut().next() {
                e.default = Some(Value::hex(0xFE));
            }
        }
        objects.push(m);
    }
    super::model(objects)
}
