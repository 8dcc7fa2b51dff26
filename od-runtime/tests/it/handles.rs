//! The handle fast path of `ObjectDictionary` (`handle`, `read_handle`, `write_handle`).
//!
//! The runtime reaches every PDO-mapped entry through a handle resolved when the mapping is
//! loaded. Two dictionaries with the same entries are compared here: [`TestOd`], which
//! implements the handle methods itself (a handle is the entry's number), and [`PlainOd`], which
//! leaves them to the trait's defaults (a handle is the key, and each access goes through
//! `read`/`write`). Both must give the same PDO bytes, bit for bit equal to a reference packing
//! written independently here, and apply received PDOs alike.

use crate::common;
use common::*;
use od_runtime::od::{AbortCode, DataType, EntryInfo, Handle, ObjectDictionary};
use od_runtime::{Device, Frame, NmtCommand, NodeId};
use proptest::prelude::*;

/// Access to the test dictionary inside either variant.
trait Inner: ObjectDictionary {
    fn inner(&self) -> &TestOd;
    fn inner_mut(&mut self) -> &mut TestOd;
}

impl Inner for TestOd {
    fn inner(&self) -> &TestOd {
        self
    }
    fn inner_mut(&mut self) -> &mut TestOd {
        self
    }
}

impl Inner for PlainOd {
    fn inner(&self) -> &TestOd {
        &self.0
    }
    fn inner_mut(&mut self) -> &mut TestOd {
        &mut self.0
    }
}

fn booted<OD: ObjectDictionary>(od: OD) -> Device<OD, (), MemStorage> {
    let mut dev = Device::new(od, (), MemStorage::default(), NodeId::new(1).unwrap());
    dev.poll(0, |_| {});
    dev
}

/// The value of an entry as the bus sees it: its bytes, zero filled to 8 (the first 8 of a
/// longer value).
fn first8(od: &TestOd, e: &EntryInfo) -> [u8; 8] {
    let mut out = [0u8; 8];
    let b = od.bytes(e.index, e.sub);
    let n = b.len().min(8);
    out[..n].copy_from_slice(&b[..n]);
    out
}

#[test]
fn handles_read_and_write_like_read_and_write() {
    let mut fast = TestOd::new();
    let mut plain = PlainOd(TestOd::new());
    fast.restore_defaults(od_runtime::od::Area::All, 1);
    plain.restore_defaults(od_runtime::od::Area::All, 1);
    for e in ENTRIES.iter() {
        let hf = fast.handle(e.index, e.sub).expect("every entry resolves");
        let hp = plain.handle(e.index, e.sub).expect("every entry resolves");
        assert_eq!(hp, Handle::from_key(e.index, e.sub), "the default handle is the key");
        assert_eq!(hp.key(), (e.index, e.sub));
        assert_eq!(fast.read_handle(hf), first8(&fast, e), "{:04X}sub{}", e.index, e.sub);
        assert_eq!(plain.read_handle(hp), first8(&fast, e), "{:04X}sub{}", e.index, e.sub);
    }
    // Writes check like `write`: length and limits.
    let h = fast.handle(0x2005, 0).unwrap();
    assert_eq!(fast.write_handle(h, &[101]), Err(AbortCode::VALUE_TOO_HIGH));
    assert_eq!(fast.write_handle(h, &[1, 2]), Err(AbortCode::LENGTH_TOO_HIGH));
    assert_eq!(fast.write_handle(h, &[0x9C]), Ok(())); // -100
    assert_eq!(fast.get(0x2005, 0), -100);
    let h = plain.handle(0x2005, 0).unwrap();
    assert_eq!(plain.write_handle(h, &[101]), Err(AbortCode::VALUE_TOO_HIGH));
    assert_eq!(plain.write_handle(h, &[0x64]), Ok(()));
    assert_eq!(plain.0.get(0x2005, 0), 100);
    // A string: the first 8 bytes, zero past its length.
    // (A generic function, not `dyn`: `ObjectDictionary` has an associated const.)
    fn string_handle(od: &mut impl Inner) {
        let h = od.handle(0x2009, 0).unwrap();
        assert_eq!(od.read_handle(h), *b"ABCDEFGH");
        od.write_handle(h, b"xyz").unwrap();
        assert_eq!(od.read_handle(h), [b'x', b'y', b'z', 0, 0, 0, 0, 0]);
        assert_eq!(od.inner().bytes(0x2009, 0), b"xyz");
    }
    string_handle(&mut fast);
    string_handle(&mut plain);
}

#[test]
fn bad_handles_read_zeros_and_refuse_writes() {
    let mut fast = TestOd::new();
    let mut plain = PlainOd(TestOd::new());
    assert_eq!(fast.handle(0x2000, 0), None);
    assert_eq!(fast.handle(0x2004, 9), None);
    assert_eq!(plain.handle(0x2000, 0), None);
    assert_eq!(plain.handle(0x2004, 9), None);
    for raw in [N as u32, 0xFFFF_FFFF, Handle::from_key(0x2000, 0).get()] {
        assert_eq!(fast.read_handle(Handle::new(raw)), [0; 8]);
        assert_eq!(fast.write_handle(Handle::new(raw), &[0]), Err(AbortCode::NO_OBJECT));
    }
    let absent = Handle::from_key(0x2000, 0);
    assert_eq!(plain.read_handle(absent), [0; 8]);
    assert_eq!(plain.write_handle(absent, &[0]), Err(AbortCode::NO_OBJECT));
}

#[test]
fn default_read_handle_of_a_long_value() {
    // The DOMAIN 2003h holds 300 bytes: more than the default's 256-byte retry buffer, so the
    // default reads zeros (as documented); 20 bytes come back as their first 8.
    let mut plain = PlainOd(TestOd::new());
    let h = plain.handle(0x2003, 0).unwrap();
    let long: Vec<u8> = (1..=20).collect();
    plain.write(0x2003, 0, &long).unwrap();
    assert_eq!(plain.read_handle(h), [1, 2, 3, 4, 5, 6, 7, 8]);
    plain.write(0x2003, 0, &[7; 300]).unwrap();
    assert_eq!(plain.read_handle(h), [0; 8]);
    let fast = plain.0.clone();
    let h = fast.handle(0x2003, 0).unwrap();
    assert_eq!(fast.read_handle(h), [7; 8]);
}

/// Every `(index, sub, bits)` a PDO of the direction may map: each mappable entry with its size
/// (a string with each of its lengths up to 8 bytes) and, for an RPDO, the dummy entries.
fn candidates(transmit: bool) -> Vec<(u16, u8, u8)> {
    let mut c = Vec::new();
    for e in ENTRIES.iter() {
        if !e.pdo_mappable() || !(if transmit { e.access.tpdo_ok() } else { e.access.rpdo_ok() }) {
            continue;
        }
        if e.data_type.is_variable_length() {
            c.extend((1..=e.byte_len().min(8) as u8).map(|k| (e.index, e.sub, 8 * k)));
        } else {
            c.push((e.index, e.sub, e.bits() as u8));
        }
    }
    if !transmit {
        c.extend([(0x0001, 0, 1), (0x0005, 0, 8), (0x0006, 0, 16), (0x0007, 0, 32)]);
    }
    c
}

/// A mapping of at most 8 entries and 64 bits, chosen by `picks` from the candidates.
fn mapping(transmit: bool, picks: &[prop::sample::Index]) -> Vec<(u16, u8, u8)> {
    let c = candidates(transmit);
    let mut out = Vec::new();
    let mut total = 0u32;
    for pick in picks {
        let (index, sub, bits) = c[pick.index(c.len())];
        if out.len() < 8 && total + u32::from(bits) <= 64 {
            total += u32::from(bits);
            out.push((index, sub, bits));
        }
    }
    out
}

/// Configures PDO 1 of a direction with `map` (disabling it while the mapping is written).
fn configure<OD: ObjectDictionary>(dev: &mut Device<OD, (), MemStorage>, transmit: bool, map: &[(u16, u8, u8)]) {
    let (comm, mapobj, cob) = if transmit { (0x1800, 0x1A00, 0x181u32) } else { (0x1400, 0x1600, 0x201u32) };
    dev.write(comm, 1, &(cob | 0x8000_0000).to_le_bytes()).unwrap();
    dev.write(mapobj, 0, &[0]).unwrap();
    for (k, &(index, sub, bits)) in map.iter().enumerate() {
        let v = u32::from(index) << 16 | u32::from(sub) << 8 | u32::from(bits);
        dev.write(mapobj, k as u8 + 1, &v.to_le_bytes()).unwrap();
    }
    dev.write(mapobj, 0, &[map.len() as u8]).unwrap();
    dev.write(comm, 2, &[if transmit { 1 } else { 255 }]).unwrap();
    dev.write(comm, 1, &cob.to_le_bytes()).unwrap();
}

/// The reference packing, one bit at a time: each value's low `bits` bits, from bit 0 of byte 0.
fn pack_reference(values: &[([u8; 8], u8)]) -> Vec<u8> {
    let total: usize = values.iter().map(|(_, b)| usize::from(*b)).sum();
    let mut out = vec![0u8; total.div_ceil(8)];
    let mut at = 0usize;
    for (v, bits) in values {
        for i in 0..usize::from(*bits) {
            if v[i / 8] >> (i % 8) & 1 != 0 {
                out[at / 8] |= 1 << (at % 8);
            }
            at += 1;
        }
    }
    out
}

/// The reference unpacking: `bits` bits from bit `at` of `data`, as little-endian bytes.
fn unpack_reference(data: &[u8; 8], at: usize, bits: u8) -> Vec<u8> {
    let mut out = vec![0u8; usize::from(bits).div_ceil(8)];
    for i in 0..usize::from(bits) {
        if data[(at + i) / 8] >> ((at + i) % 8) & 1 != 0 {
            out[i / 8] |= 1 << (i % 8);
        }
    }
    out
}

fn info(index: u16, sub: u8) -> &'static EntryInfo {
    ENTRIES.iter().find(|e| e.index == index && e.sub == sub).unwrap()
}

/// Sets the mapped entries to `values` (raw bits, cut to each type), sends a SYNC and returns
/// the TPDO's data.
fn sync_tpdo<OD: Inner>(od: OD, map: &[(u16, u8, u8)], values: &[u64], strings: &[Vec<u8>]) -> Vec<u8> {
    let mut dev = booted(od);
    configure(&mut dev, true, map);
    for (k, &(index, sub, _)) in map.iter().enumerate() {
        let e = info(index, sub);
        if e.data_type.is_variable_length() {
            dev.od_mut().inner_mut().write(index, sub, &strings[k]).unwrap();
        } else if e.data_type == DataType::Boolean {
            dev.od_mut().inner_mut().set(index, sub, i128::from(values[k] & 1));
        } else {
            dev.od_mut().inner_mut().set(index, sub, i128::from(values[k]));
        }
    }
    dev.nmt_command(NmtCommand::Start, 0);
    let mut out = Vec::new();
    dev.poll(0, |_| {});
    dev.on_frame(&Frame::new(0x080, &[]).unwrap(), 0);
    dev.poll(0, |f| {
        if f.id() == 0x181 {
            out.push(f.data().to_vec())
        }
    });
    assert_eq!(out.len(), 1, "one TPDO per SYNC");
    out.remove(0)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn tpdo_bytes_match_the_reference_packing(
        picks in prop::collection::vec(any::<prop::sample::Index>(), 1..12),
        values in prop::collection::vec(any::<u64>(), 8),
        strings in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..=16), 8),
    ) {
        let map = mapping(true, &picks);
        prop_assume!(!map.is_empty());
        let fast = sync_tpdo(TestOd::new(), &map, &values, &strings);
        let plain = sync_tpdo(PlainOd(TestOd::new()), &map, &values, &strings);
        // The reference: what the dictionary holds, read through `read`, packed bit by bit.
        let mut od = TestOd::new();
        od.restore_defaults(od_runtime::od::Area::All, 1);
        let mut packed = Vec::new();
        for (k, &(index, sub, bits)) in map.iter().enumerate() {
            let e = info(index, sub);
            if e.data_type.is_variable_length() {
                od.write(index, sub, &strings[k]).unwrap();
            } else if e.data_type == DataType::Boolean {
                od.set(index, sub, i128::from(values[k] & 1));
            } else {
                od.set(index, sub, i128::from(values[k]));
            }
            packed.push((first8(&od, e), bits));
        }
        // Entries mapped twice hold the value set last: read them again after all sets.
        let packed: Vec<([u8; 8], u8)> =
            map.iter().zip(&packed).map(|(&(index, sub, _), (_, bits))| (first8(&od, info(index, sub)), *bits)).collect();
        let want = pack_reference(&packed);
        prop_assert_eq!(&fast, &want);
        prop_assert_eq!(&plain, &want);
    }

    #[test]
    fn rpdo_entries_match_the_reference_unpacking(
        picks in prop::collection::vec(any::<prop::sample::Index>(), 1..12),
        data in any::<[u8; 8]>(),
    ) {
        let map = mapping(false, &picks);
        prop_assume!(!map.is_empty());
        let mut fast = booted(TestOd::new());
        let mut plain = booted(PlainOd(TestOd::new()));
        configure(&mut fast, false, &map);
        configure(&mut plain, false, &map);
        fast.nmt_command(NmtCommand::Start, 0);
        plain.nmt_command(NmtCommand::Start, 0);
        // The expected dictionary: each entry written in mapping order with the runtime's own
        // length and limit rule (a refused value leaves the entry as it was).
        let mut want = fast.od().clone();
        let mut at = 0usize;
        for &(index, sub, bits) in &map {
            if index > 7 {
                let v = unpack_reference(&data, at, bits);
                if info(index, sub).check_value(&v).is_ok() {
                    want.write(index, sub, &v).unwrap();
                }
            }
            at += usize::from(bits);
        }
        let frame = Frame::new(0x201, &data).unwrap();
        fast.on_frame(&frame, 0);
        plain.on_frame(&frame, 0);
        for &(index, sub, _) in map.iter().filter(|m| m.0 > 7) {
            prop_assert_eq!(fast.od().bytes(index, sub), want.bytes(index, sub), "{:04X}sub{}", index, sub);
            prop_assert_eq!(plain.od().0.bytes(index, sub), want.bytes(index, sub), "{:04X}sub{}", index, sub);
        }
    }
}
