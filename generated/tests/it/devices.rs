//! Every generated device module against the description it came from: the run-time mapping
//! check (generated code calling `od_runtime::pdo`) must agree with the generation-time check
//! (`od_codegen::pdo::check_mapping` on the model), and the dictionaries must be consistent.

use od_codegen::pdo::Direction;
use od_runtime::od::{Area, ObjectDictionary};
use proptest::prelude::*;

fn model(rel: &str) -> eds::Model {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel);
    let bytes = std::fs::read(&path).unwrap();
    eds::parse(rel, &bytes, &eds::Options::lenient()).model
}

/// A random mapping entry: mostly real entries of the dictionary with their own or a random
/// length, sometimes dummies or objects that do not exist.
fn mapping_entry(entries: &'static [od_runtime::od::EntryInfo]) -> impl Strategy<Value = u32> {
    prop_oneof![
        4 => (0..entries.len(), any::<bool>(), 0u32..=72).prop_map(move |(i, own, bits)| {
            let e = &entries[i];
            let bits = if own { e.bits().min(255) } else { bits };
            (u32::from(e.index) << 16) | (u32::from(e.sub) << 8) | bits
        }),
        1 => (1u32..=7, prop_oneof![Just(1u32), Just(8), Just(16), Just(32)]).prop_map(|(i, b)| (i << 16) | b),
        1 => any::<u32>(),
    ]
}

macro_rules! device_tests {
    ($feature:literal, $module:ident, $file:literal) => {
        #[cfg(feature = $feature)]
        mod $module {
            use super::*;
            use generated::$module::{Dictionary, ENTRIES, ROWS};

            #[test]
            fn table_covers_the_model() {
                let m = model($file);
                let od = Dictionary::new(3);
                for (obj, e) in m.entries() {
                    if matches!(e.data_type, eds::model::DataType::Other(_)) || !matches!(obj.object_type, eds::model::ObjectType::Var | eds::model::ObjectType::Array | eds::model::ObjectType::Record | eds::model::ObjectType::Domain) {
                        continue;
                    }
                    let info = od.info(obj.index.0, e.sub.0).unwrap();
                    assert_eq!(info.pdo_mappable(), e.pdo_mapping, "0x{:04X} sub {}", obj.index.0, e.sub.0);
                    let name = od.name(obj.index.0, e.sub.0).unwrap();
                    assert_eq!(name.rsplit(": ").next().unwrap(), e.name.trim());
                }
                assert!(ENTRIES.windows(2).all(|w| (w[0].index, w[0].sub) < (w[1].index, w[1].sub)));
                // The device's rows, decoded, are the public table, position by position.
                assert_eq!((ROWS.len(), od.entry_count()), (ENTRIES.len(), ENTRIES.len()));
                for (pos, e) in ENTRIES.iter().enumerate() {
                    assert_eq!(od.entry_at(pos).as_ref(), Some(e), "entry {pos}");
                    assert_eq!((ROWS[pos].index, ROWS[pos].sub, ROWS[pos].data_type), (e.index, e.sub, e.data_type));
                }
                assert_eq!(od.entry_at(ENTRIES.len()), None);
                // Each row's size byte is its data type's size (the capacity of a buffer is in
                // its extras), so `bits()` is what it was before the byte held it.
                for e in ENTRIES.iter() {
                    assert_eq!(e.flags.bits(), e.data_type.bits(), "0x{:04X} sub {}", e.index, e.sub);
                    let capacity = e.extras.map_or(0, |x| x.bits);
                    assert_eq!(e.bits(), if capacity != 0 { capacity } else { e.data_type.bits() });
                }
            }

            #[test]
            fn lookup_agrees_with_a_search_of_the_table_for_every_index() {
                use od_runtime::od::AbortCode;
                let od = Dictionary::new(3);
                for index in 0..=u16::MAX {
                    let here: Vec<u8> = ENTRIES.iter().filter(|e| e.index == index).map(|e| e.sub).collect();
                    let probes = here.iter().copied().chain([0, 1, 2, 0x7F, 0xFE, 0xFF]);
                    for sub in probes {
                        let want = match ENTRIES.iter().position(|e| (e.index, e.sub) == (index, sub)) {
                            Some(p) => Ok(p),
                            None if here.is_empty() => Err(AbortCode::NO_OBJECT),
                            None => Err(AbortCode::NO_SUB_INDEX),
                        };
                        assert_eq!(Dictionary::position(index, sub), want, "0x{index:04X} sub {sub}");
                        // A microcontroller's lookup (no direct table): a binary search.
                        let sorted = od_runtime::__private_v3::position_sorted(&ROWS, index, sub);
                        assert_eq!(sorted, want, "0x{index:04X} sub {sub}, binary search");
                        assert_eq!(od.info(index, sub).map(|e| (e.index, e.sub)), want.map(|_| (index, sub)));
                        // What the device reads (decoded from ROWS) is the public table's row.
                        assert_eq!(od.entry(index, sub), od.info(index, sub).copied(), "0x{index:04X} sub {sub}");
                    }
                }
            }

            #[test]
            fn the_services_are_those_the_dictionary_has_objects_for() {
                use od_runtime::od::{ObjectDictionary, Services};
                let s = <Dictionary as ObjectDictionary>::SERVICES;
                assert_eq!(s, Services::of(&ENTRIES));
                let has = |index: u16| ENTRIES.iter().any(|e| e.index == index);
                let pdos = ENTRIES.iter().any(|e| matches!(e.index, 0x1400..=0x15FF | 0x1800..=0x19FF));
                assert_eq!(s.sync, has(0x1005) || pdos, "SYNC with 1005h, or with PDOs (which may be synchronous)");
                assert_eq!(s.node_guarding, has(0x100C) && has(0x100D));
                assert_eq!(s.heartbeat_consumer, has(0x1016));
                assert_eq!(s.emcy_history, has(0x1003));
            }

            #[test]
            fn every_value_reads_back_and_restores() {
                let mut od = Dictionary::new(3);
                let mut buf = [0u8; 256];
                for e in ENTRIES.iter() {
                    let n = od.read(e.index, e.sub, &mut buf).unwrap();
                    od.write(e.index, e.sub, &buf[..n]).unwrap();
                }
                assert_eq!(od, Dictionary::new(3));
                od.restore_defaults(Area::All, 3);
                assert_eq!(od, Dictionary::new(3));
            }

            /// The handle fast path (what the runtime uses for mapped PDO entries) against the
            /// keyed path, entry by entry: same bytes read, same outcome and state on writes.
            #[test]
            fn handles_agree_with_keyed_access_for_every_entry() {
                use od_runtime::od::AbortCode;
                let mut keyed = Dictionary::new(3);
                let mut fast = Dictionary::new(3);
                let mut buf = [0u8; 256];
                for (pos, e) in ENTRIES.iter().enumerate() {
                    let h = fast.handle(e.index, e.sub).unwrap();
                    let n = keyed.read(e.index, e.sub, &mut buf).unwrap();
                    let mut want = [0u8; 8];
                    want[..n.min(8)].copy_from_slice(&buf[..n.min(8)]);
                    assert_eq!(fast.read_handle(h), want, "0x{:04X} sub {}", e.index, e.sub);
                    // A value that is not the default: every bit of the entry's bytes flipped,
                    // then one byte short and one byte long.
                    let flipped: Vec<u8> = buf[..n].iter().map(|b| !b).collect();
                    let tries = [flipped.clone(), flipped[..n.saturating_sub(1)].to_vec(), [flipped.as_slice(), &[0]].concat()];
                    for data in tries.iter() {
                        assert_eq!(fast.write_handle(h, data), keyed.write(e.index, e.sub, data), "0x{:04X} sub {} <- {data:02X?}", e.index, e.sub);
                        assert_eq!(fast, keyed, "entry {pos}");
                    }
                }
                // A handle past the table is refused, never a panic.
                let past = od_runtime::od::Handle::new(ENTRIES.len() as u32);
                assert_eq!(fast.read_handle(past), [0; 8]);
                assert_eq!(fast.write_handle(past, &[0]), Err(AbortCode::NO_OBJECT));
                assert!(fast.handle(0x0000, 0).is_none());
            }

            /// `read_mapped` (the generated packing loop the runtime calls on every SYNC)
            /// against packing the keyed reads by hand, for pseudo-random valid TPDO mappings
            /// of the entries holding values other than their defaults.
            #[test]
            fn packed_mappings_agree_with_keyed_reads() {
                use od_runtime::od::MappedHandle;
                let raw = |e: &od_runtime::od::EntryInfo| (u32::from(e.index) << 16) | (u32::from(e.sub) << 8) | e.bits().min(255);
                let mappable: Vec<&od_runtime::od::EntryInfo> =
                    ENTRIES.iter().filter(|e| Dictionary::check_tpdo_mapping(&[raw(e)]).is_ok()).collect();
                let mut od = Dictionary::new(3);
                let mut buf = [0u8; 256];
                let mut rng = 0x9E37_79B9_7F4A_7C15u64;
                let mut next = move || {
                    rng ^= rng << 13;
                    rng ^= rng >> 7;
                    rng ^= rng << 17;
                    rng
                };
                // Every mappable entry away from its default (writes a limit refuses keep it).
                for e in &mappable {
                    let n = od.read(e.index, e.sub, &mut buf).unwrap();
                    let data: Vec<u8> = next().to_le_bytes().iter().cycle().take(n).copied().collect();
                    let _ = od.write(e.index, e.sub, &data);
                }
                let mut packed = 0;
                for _ in 0..if mappable.is_empty() { 0 } else { 2000 } {
                    let mut map = Vec::new();
                    let mut total = 0;
                    for _ in 0..(next() % 9) {
                        let e = mappable[(next() % mappable.len() as u64) as usize];
                        if total + e.bits() > 64 {
                            break;
                        }
                        total += e.bits();
                        let handle = od.handle(e.index, e.sub).unwrap();
                        map.push(MappedHandle { index: e.index, sub: e.sub, bits: e.bits() as u8, handle });
                    }
                    let raws: Vec<u32> = map.iter().map(|m| (u32::from(m.index) << 16) | (u32::from(m.sub) << 8) | u32::from(m.bits)).collect();
                    assert_eq!(Dictionary::check_tpdo_mapping(&raws), Ok(total));
                    let (mut want, mut offset) = (0u64, 0u32);
                    for m in &map {
                        let n = od.read(m.index, m.sub, &mut buf).unwrap();
                        let mut b = [0u8; 8];
                        b[..n.min(8)].copy_from_slice(&buf[..n.min(8)]);
                        let v = u64::from_le_bytes(b);
                        let v = if m.bits == 64 { v } else { v & ((1 << m.bits) - 1) };
                        want |= v << offset;
                        offset += u32::from(m.bits);
                    }
                    assert_eq!(od.read_mapped(&map), want, "{raws:08X?}");
                    packed += usize::from(want != 0);
                }
                assert!(mappable.is_empty() || packed > 1000, "{packed} mappings with data");
            }

            static MODEL: std::sync::LazyLock<eds::Model> = std::sync::LazyLock::new(|| model($file));
            static CHECKER: std::sync::LazyLock<od_codegen::pdo::MappingChecker<'static>> = std::sync::LazyLock::new(|| {
                od_codegen::pdo::MappingChecker::new(&MODEL, &od_codegen::Options::new(stringify!($module), $file))
            });

            proptest! {
                #![proptest_config(ProptestConfig::with_cases(512))]
                #[test]
                fn run_time_and_generation_time_checks_agree(
                    raw in proptest::collection::vec(mapping_entry(&ENTRIES), 0..6),
                    rpdo: bool,
                ) {
                    let dir = if rpdo { Direction::Receive } else { Direction::Transmit };
                    let generation = CHECKER.check(dir, &raw).map_err(|e| e.abort_code);
                    let run = if rpdo { Dictionary::check_rpdo_mapping(&raw) } else { Dictionary::check_tpdo_mapping(&raw) };
                    prop_assert_eq!(generation, run.map_err(|c| c.0));
                }
            }
        }
    };
}

device_tests!("drvi", drvi, "devices/camozzi-drvi.eds");
device_tests!("drcs", drcs, "devices/camozzi-drcs.eds");
device_tests!("akd", akd, "devices/kollmorgen-akd.eds");
device_tests!("fixtures", fixture_mini, "od-codegen/tests/fixtures/mini.eds");

#[cfg(feature = "drvi")]
#[test]
fn drvi_default_pdos() {
    use generated::drvi::{Dictionary, pdo};
    let mut od = Dictionary::new(32);
    od.set_statusword(0x0637).unwrap();
    assert_eq!(pdo::Tpdo1::from_dictionary(&od).pack(), [0x37, 0x06]);
    pdo::Rpdo1::unpack(&[0x0F, 0x00]).unwrap().to_dictionary(&mut od).unwrap();
    assert_eq!(od.controlword(), 0x000F);
    assert_eq!(Dictionary::check_rpdo_mapping(&pdo::Rpdo1::MAPPING), Ok(16));
}
