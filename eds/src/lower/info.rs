//! Pass 2: the information sections and the object lists.

use super::sections::{KeySet, Keys, Kind, Kv, Section, Sections, match_keys, report_duplicate};
use super::{Crumbs, Ctx, FastMap};
use crate::codes;
use crate::model::{Category, Commissioning, DeviceInfo, ExtraSection, FileInfo, Model, Radix};
use crate::source::Span;
use crate::value::parse_int;

/// The CiA 306 baud rates in kbit/s (`BaudRate_10` ... `BaudRate_1000`).
pub(crate) const BAUD_RATES: [u16; 8] = [10, 20, 50, 125, 250, 500, 800, 1000];

fn owned(kv: &Kv<'_>) -> (String, String) {
    (kv.key().to_owned(), kv.value().to_owned())
}

/// Reads an unsigned number for an information key; reports E0503 and returns `None` when it
/// cannot be read or does not fit `max`.
#[inline]
fn info_uint(cx: &mut Ctx<'_>, kv: &Kv<'_>, max: u64, section: &str) -> Option<u64> {
    // A plain number in range, as most are, needs neither the comment split nor the general
    // reader (which reads it as the same number), nor a call.
    if let Some((n, _)) = crate::value::parse_plain_uint(kv.value())
        && n <= max
    {
        return Some(n);
    }
    info_uint_general(cx, kv, max, section)
}

/// [`info_uint`] for a value that is not a plain number in range.
fn info_uint_general(cx: &mut Ctx<'_>, kv: &Kv<'_>, max: u64, section: &str) -> Option<u64> {
    let v = kv.value().split(';').next().unwrap_or("").trim();
    if v.is_empty() {
        let d = cx.emit(
            codes::E0503,
            Some(kv.value_span(&cx.src.text)),
            super::cat(["[", section, "] ", kv.key(), " is empty"]),
        );
        d.hint = Some(super::cat(["write a number or remove the `", kv.key(), "=` line"]).into());
        return None;
    }
    // (Quirks go unreported here; the context's buffer takes them.)
    let parsed = cx.with_quirks(|_, quirks| parse_int(v, quirks));
    match parsed {
        Ok(p) if p.value >= 0 && p.value as u128 <= max as u128 => Some(p.value as u64),
        Ok(p) => {
            cx.emit(
                codes::E0503,
                Some(kv.value_span(&cx.src.text)),
                format!("[{section}] {}={} is out of range 0..={max}", kv.key(), p.value),
            );
            None
        }
        Err(_) => {
            let d = cx.emit(
                codes::E0503,
                Some(kv.value_span(&cx.src.text)),
                format!("[{section}] {}: `{}` is not a number (kept as text)", kv.key(), kv.value()),
            );
            d.hint = Some("write a decimal number or a 0x-prefixed hexadecimal number".into());
            None
        }
    }
}

#[inline]
fn info_bool(cx: &mut Ctx<'_>, kv: &Kv<'_>, section: &str) -> Option<bool> {
    // (As nearly every file writes them: no comment to split off, nothing to trim, no call.)
    match kv.value().as_bytes() {
        b"0" => Some(false),
        b"1" => Some(true),
        _ => info_bool_general(cx, kv, section),
    }
}

/// [`info_bool`] for a value other than a plain `0` or `1`.
fn info_bool_general(cx: &mut Ctx<'_>, kv: &Kv<'_>, section: &str) -> Option<bool> {
    let v = kv.value().split(';').next().unwrap_or("").trim();
    match v {
        "0" => Some(false),
        "1" => Some(true),
        _ if v.eq_ignore_ascii_case("true") || v.eq_ignore_ascii_case("false") => {
            let b = v.eq_ignore_ascii_case("true");
            let d =
                cx.emit(codes::E0503, Some(kv.value_span(&cx.src.text)), format!("[{section}] {} is `{v}`", kv.key()));
            d.hint = Some(format!("CiA 306 writes booleans as 0 or 1: write `{}`", b as u8).into());
            Some(b)
        }
        _ => {
            let d = cx.emit(
                codes::E0503,
                Some(kv.value_span(&cx.src.text)),
                format!("[{section}] {}: `{}` is not 0 or 1 (kept as text)", kv.key(), kv.value()),
            );
            d.hint = Some("write 0 (not supported) or 1 (supported)".into());
            None
        }
    }
}

/// The data type a `DummyNNNN` key names: `Dummy` in any case and four hex digits.
#[inline]
fn dummy_type(key: &str) -> Option<u16> {
    match *key.as_bytes() {
        [d, u, m1, m2, y, a, b, c, e] if [d, u, m1, m2, y].eq_ignore_ascii_case(b"Dummy") => {
            crate::value::hex4_value([a, b, c, e])
        }
        _ => None,
    }
}

/// The rate of a `BaudRate_<kbit/s>` key as CiA 306 writes it (`BaudRate_` and one to four
/// digits without a leading zero, or `0`), read without the general number parser; `None` for
/// any other key (which the general rules then look at).
#[inline]
fn canonical_baud_rate(key: &str) -> Option<u16> {
    let digits = key.strip_prefix("BaudRate_")?.as_bytes();
    if digits.is_empty() || digits.len() > 4 || (digits[0] == b'0' && digits.len() > 1) {
        return None;
    }
    let mut v = 0u16;
    for &c in digits {
        let d = c.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        v = v * 10 + d as u16;
    }
    Some(v)
}

fn missing_keys<const N: usize>(
    cx: &mut Ctx<'_>,
    sec: &Section<'_>,
    known: &KeySet<N>,
    keys: &Keys<'_, N>,
    required: &[&str],
) {
    let missing: Vec<&str> = required
        .iter()
        .copied()
        .filter(|r| known.names.iter().position(|k| k == r).is_none_or(|i| keys.get(i).is_none()))
        .collect();
    if !missing.is_empty() {
        let d = cx.emit(codes::E0505, Some(sec.name_span), {
            // "[DeviceInfo] lacks `A`, `B`", without a formatter.
            let mut message = super::cat(["[", sec.name, "] lacks "]);
            for (i, m) in missing.iter().enumerate() {
                message.push_str(if i == 0 { "`" } else { ", `" });
                message.push_str(m);
                message.push('`');
            }
            message
        });
        d.hint = Some("CiA 306 requires these keys".into());
    }
}

/// Checks `mm-dd-yyyy`.
fn is_date(s: &str) -> bool {
    let b = s.as_bytes();
    b.len() == 10
        && b[2] == b'-'
        && b[5] == b'-'
        && b.iter().enumerate().all(|(i, c)| i == 2 || i == 5 || c.is_ascii_digit())
}

/// Checks `hh:mm(AM|PM)`.
fn is_time(s: &str) -> bool {
    let Some(t) = s
        .strip_suffix("AM")
        .or_else(|| s.strip_suffix("PM"))
        .or_else(|| s.strip_suffix("am").or_else(|| s.strip_suffix("pm")))
    else {
        return false;
    };
    let Some((h, m)) = t.split_once(':') else { return false };
    (1..=2).contains(&h.len())
        && m.len() == 2
        && h.bytes().all(|c| c.is_ascii_digit())
        && m.bytes().all(|c| c.is_ascii_digit())
        && h.parse::<u8>().is_ok_and(|h| h <= 12)
        && m.parse::<u8>().is_ok_and(|m| m < 60)
}

const FILE_INFO_KEYS: KeySet<12> = KeySet::new([
    "FileName",
    "FileVersion",
    "FileRevision",
    "EDSVersion",
    "Description",
    "CreationTime",
    "CreationDate",
    "CreatedBy",
    "ModificationTime",
    "ModificationDate",
    "ModifiedBy",
    "LastEDS",
]);

fn lower_file_info(cx: &mut Ctx<'_>, sec: &Section<'_>) -> FileInfo {
    let keys = match_keys(cx, sec, &FILE_INFO_KEYS, Crumbs::default(), true);
    let mut fi = FileInfo::default();
    let s = |i: usize| keys.get(i).map(|kv| kv.value().to_owned());
    fi.file_name = s(0);
    fi.eds_version = s(3);
    fi.description = s(4);
    fi.creation_time = s(5);
    fi.creation_date = s(6);
    fi.created_by = s(7);
    fi.modification_time = s(8);
    fi.modification_date = s(9);
    fi.modified_by = s(10);
    for (i, slot) in [(1, &mut fi.file_version), (2, &mut fi.file_revision)] {
        if let Some(kv) = keys.get(i) {
            // CiA 306 makes both Unsigned8.
            *slot = info_uint(cx, kv, 0xFF, "FileInfo").map(|v| v as u32);
            if slot.is_none() {
                fi.extra.push(owned(kv));
            }
        }
    }
    for (i, check, form) in [
        (5, is_time as fn(&str) -> bool, "hh:mmAM"),
        (6, is_date, "mm-dd-yyyy"),
        (8, is_time, "hh:mmAM"),
        (9, is_date, "mm-dd-yyyy"),
    ] {
        if let Some(kv) = keys.get(i)
            && !kv.value().is_empty()
            && !check(kv.value())
        {
            let d = cx.emit(
                codes::E0503,
                Some(kv.value_span(&cx.src.text)),
                super::cat(["[FileInfo] ", kv.key(), "=`", kv.value(), "` is not in the CiA 306 form ", form]),
            );
            d.hint = Some(super::cat(["write it as ", form]).into());
        }
    }
    if let Some(kv) = keys.get(3) {
        let ok = kv.value().split_once('.').is_some_and(|(a, b)| {
            !a.is_empty()
                && !b.is_empty()
                && a.bytes().all(|c| c.is_ascii_digit())
                && b.bytes().all(|c| c.is_ascii_digit())
        });
        if !ok {
            let d = cx.emit(
                codes::E0503,
                Some(kv.value_span(&cx.src.text)),
                format!("[FileInfo] EDSVersion=`{}` is not `major.minor`", kv.value()),
            );
            d.hint = Some("CiA 306 files are EDSVersion=4.0".into());
        }
    }
    if let Some(kv) = keys.get(11) {
        fi.extra.push(owned(kv));
    }
    fi.extra.extend(keys.unknown.iter().map(|kv| owned(kv)));
    missing_keys(cx, sec, &FILE_INFO_KEYS, &keys, &["FileName", "FileVersion", "FileRevision", "EDSVersion"]);
    fi
}

const DEVICE_INFO_KEYS: KeySet<21> = KeySet::new([
    "VendorName",
    "VendorNumber",
    "ProductName",
    "ProductNumber",
    "RevisionNumber",
    "OrderCode",
    "SimpleBootUpMaster",
    "SimpleBootUpSlave",
    "Granularity",
    "DynamicChannelsSupported",
    "GroupMessaging",
    "NrOfRXPDO",
    "NrOfTXPDO",
    "LSS_Supported",
    "CompactPDO",
    // Reserved by CiA 306 for compatibility: kept as written, not interpreted.
    "ProductVersion",
    "ProductRevision",
    "LMT_ManufacturerName",
    "LMT_ProductName",
    "ExtendedBootUpMaster",
    "ExtendedBootUpSlave",
]);

fn lower_device_info(cx: &mut Ctx<'_>, sec: &Section<'_>) -> DeviceInfo {
    const S: &str = "DeviceInfo";
    let keys = match_keys(cx, sec, &DEVICE_INFO_KEYS, Crumbs::default(), false);
    let mut di = DeviceInfo {
        vendor_name: keys.get(0).map(|kv| kv.value().to_owned()),
        product_name: keys.get(2).map(|kv| kv.value().to_owned()),
        order_code: keys.get(5).map(|kv| kv.value().to_owned()),
        ..Default::default()
    };
    let mut keep = Vec::new();
    macro_rules! uint {
        ($i:expr, $field:ident, $max:expr, $t:ty) => {
            if let Some(kv) = keys.get($i) {
                di.$field = info_uint(cx, kv, $max, S).map(|v| v as $t);
                if di.$field.is_none() {
                    keep.push(owned(kv));
                }
            }
        };
    }
    macro_rules! boolean {
        ($i:expr, $field:ident) => {
            if let Some(kv) = keys.get($i) {
                di.$field = info_bool(cx, kv, S);
                if di.$field.is_none() {
                    keep.push(owned(kv));
                }
            }
        };
    }
    uint!(1, vendor_number, u32::MAX as u64, u32);
    uint!(3, product_number, u32::MAX as u64, u32);
    uint!(4, revision_number, u32::MAX as u64, u32);
    boolean!(6, simple_boot_up_master);
    boolean!(7, simple_boot_up_slave);
    uint!(8, granularity, 64, u8);
    uint!(9, dynamic_channels_supported, 0xFF, u8);
    boolean!(10, group_messaging);
    uint!(11, nr_of_rx_pdo, 512, u16);
    uint!(12, nr_of_tx_pdo, 512, u16);
    boolean!(13, lss_supported);
    uint!(14, compact_pdo, 0xFF, u8);
    if let (Some(bits), Some(kv)) = (di.compact_pdo.filter(|&b| b != 0), keys.get(14)) {
        let d = cx.emit(
            codes::E0612,
            Some(kv.value_span(&cx.src.text)),
            format!(
                "CompactPDO=0x{bits:02X}: the file leaves PDO objects implied; the model holds only those written out"
            ),
        );
        d.hint = Some("call eds::lower::expand_compact_pdo to add the implied PDO objects".into());
    }
    for i in 15..DEVICE_INFO_KEYS.names.len() {
        if let Some(kv) = keys.get(i) {
            keep.push(owned(kv));
        }
    }
    for kv in &keys.unknown {
        // BaudRate_<kbit/s>: any rate is read; the CiA 306 ones are not reported.
        let rate = match canonical_baud_rate(kv.key()) {
            Some(r) => Some(r),
            None => kv
                .key()
                .get(..9)
                .filter(|p| p.eq_ignore_ascii_case("BaudRate_"))
                .and_then(|_| kv.key()[9..].parse::<u16>().ok()),
        };
        match rate {
            Some(r) => {
                // As CiA 306 writes it: `BaudRate_` and the number without a sign or leading
                // zeros (every file has several of these keys: no string is built to compare).
                let digits = &kv.key()[9..];
                let canonical = kv.key().starts_with("BaudRate_")
                    && digits.bytes().all(|b| b.is_ascii_digit())
                    && (digits == "0" || !digits.starts_with('0'));
                if !canonical {
                    let canon = format!("BaudRate_{r}");
                    let d = cx.emit(
                        codes::E0104,
                        Some(kv.key_span(&cx.src.text)),
                        format!("key `{}` is written `{canon}` in CiA 306", kv.key()),
                    );
                    d.hint = Some(format!("write `{canon}`").into());
                }
                if !BAUD_RATES.contains(&r) {
                    let d = cx.emit(
                        codes::E0503,
                        Some(kv.key_span(&cx.src.text)),
                        format!("{r} kbit/s is not a CiA 301 bit rate"),
                    );
                    d.hint = Some("CiA 306 knows BaudRate_10, _20, _50, _125, _250, _500, _800 and _1000".into());
                }
                if let Some(b) = info_bool(cx, kv, S) {
                    di.baud_rates.insert(r, b);
                } else {
                    keep.push(owned(kv));
                }
            }
            None => {
                cx.emit(
                    codes::E0102,
                    Some(kv.key_span(&cx.src.text)),
                    format!("key `{}` is not a CiA 306 key of [DeviceInfo]; it is kept as written", kv.key()),
                );
                keep.push(owned(kv));
            }
        }
    }
    di.extra = keep;
    missing_keys(
        cx,
        sec,
        &DEVICE_INFO_KEYS,
        &keys,
        &[
            "VendorName",
            "ProductName",
            "Granularity",
            "NrOfRXPDO",
            "NrOfTXPDO",
            "SimpleBootUpMaster",
            "SimpleBootUpSlave",
        ],
    );
    if !di.baud_rates.values().any(|&b| b) {
        let d = cx.emit(codes::E0505, Some(sec.name_span), "[DeviceInfo] names no supported bit rate");
        d.hint = Some("add `BaudRate_<kbit/s>=1` for each bit rate the device supports".into());
    }
    di
}

const COMMISSIONING_KEYS: KeySet<7> =
    KeySet::new(["NodeID", "NodeName", "Baudrate", "NetNumber", "NetworkName", "CANopenManager", "LSS_SerialNumber"]);

fn lower_commissioning(cx: &mut Ctx<'_>, sec: &Section<'_>) -> Commissioning {
    const S: &str = "DeviceComissioning";
    let keys = match_keys(cx, sec, &COMMISSIONING_KEYS, Crumbs::default(), true);
    let mut c = Commissioning { node_name: keys.get(1).map(|kv| kv.value().to_owned()), ..Default::default() };
    c.network_name = keys.get(4).map(|kv| kv.value().to_owned());
    let mut keep = Vec::new();
    if let Some(kv) = keys.get(0) {
        match info_uint(cx, kv, 0xFF, S) {
            Some(n) => {
                if !(1..=127).contains(&n) {
                    let d = cx.emit(
                        codes::E0506,
                        Some(kv.value_span(&cx.src.text)),
                        format!("node id {n} is outside 1..=127"),
                    );
                    d.hint = Some("CANopen node ids are 1..=127".into());
                }
                c.node_id = Some(n as u8);
            }
            None => keep.push(owned(kv)),
        }
    }
    if let Some(kv) = keys.get(2) {
        c.baudrate = info_uint(cx, kv, 0xFFFF, S).map(|v| v as u16);
        if let Some(b) = c.baudrate
            && !BAUD_RATES.contains(&b)
        {
            cx.emit(codes::E0503, Some(kv.value_span(&cx.src.text)), format!("{b} kbit/s is not a CiA 301 bit rate"));
        }
        if c.baudrate.is_none() {
            keep.push(owned(kv));
        }
    }
    if let Some(kv) = keys.get(3) {
        c.net_number = info_uint(cx, kv, u32::MAX as u64, S).map(|v| v as u32);
        if c.net_number.is_none() {
            keep.push(owned(kv));
        }
    }
    if let Some(kv) = keys.get(5) {
        c.canopen_manager = info_bool(cx, kv, S);
        if c.canopen_manager.is_none() {
            keep.push(owned(kv));
        }
    }
    if let Some(kv) = keys.get(6) {
        c.lss_serial_number = info_uint(cx, kv, u32::MAX as u64, S).map(|v| v as u32);
        if c.lss_serial_number.is_none() {
            keep.push(owned(kv));
        }
    }
    keep.extend(keys.unknown.iter().map(|kv| owned(kv)));
    c.extra = keep;
    c
}

fn lower_dummy_usage(cx: &mut Ctx<'_>, sec: &Section<'_>, model: &mut Model) {
    const NO_KEYS: KeySet<0> = KeySet::new([]);
    let keys = match_keys(cx, sec, &NO_KEYS, Crumbs::default(), false);
    for kv in &keys.unknown {
        let ty = dummy_type(kv.key());
        match ty {
            Some(t) => {
                if !(1..=7).contains(&t) {
                    let d = cx.emit(
                        codes::E0503,
                        Some(kv.key_span(&cx.src.text)),
                        super::cat(["`", kv.key(), "` names no basic data type (0001..0007)"]),
                    );
                    d.hint = Some("dummy mapping exists for the data types 0x0001..=0x0007".into());
                }
                if !kv.key().starts_with("Dummy") {
                    cx.emit(
                        codes::E0104,
                        Some(kv.key_span(&cx.src.text)),
                        format!("key `{}` is written `Dummy{t:04X}` in CiA 306", kv.key()),
                    );
                }
                if let Some(b) = info_bool(cx, kv, "DummyUsage") {
                    model.dummy_usage.insert(t, b);
                }
            }
            None => {
                let d = cx.emit(
                    codes::E0503,
                    Some(kv.key_span(&cx.src.text)),
                    format!("`{}` is not a `DummyNNNN` key (ignored)", kv.key()),
                );
                d.hint = Some("[DummyUsage] entries are `Dummy0001=1` ... `Dummy0007=1`".into());
            }
        }
    }
}

fn lower_comments(cx: &mut Ctx<'_>, sec: &Section<'_>, model: &mut Model) {
    const LINES: KeySet<1> = KeySet::new(["Lines"]);
    let keys = match_keys(cx, sec, &LINES, Crumbs::default(), false);
    let mut lines: Vec<(u32, &str)> = Vec::new();
    for kv in &keys.unknown {
        let n = kv
            .key()
            .get(..4)
            .filter(|p| p.eq_ignore_ascii_case("Line"))
            .and_then(|_| kv.key()[4..].parse::<u32>().ok());
        match n {
            Some(n) => {
                if !kv.key().starts_with("Line") {
                    let d = cx.emit(
                        codes::E0104,
                        Some(kv.key_span(&cx.src.text)),
                        format!("key `{}` is written `Line{n}` in CiA 306", kv.key()),
                    );
                    d.hint = Some(
                        format!("write `Line{n}`; tools that match keys exactly (python-canopen) miss this line")
                            .into(),
                    );
                }
                lines.push((n, kv.value()))
            }
            None => {
                cx.emit(
                    codes::E0102,
                    Some(kv.key_span(&cx.src.text)),
                    format!("key `{}` is not a CiA 306 key of [Comments] (ignored)", kv.key()),
                )
                .hint = Some("comment lines are `Line1=...`, `Line2=...`".into());
            }
        }
    }
    lines.sort_by_key(|&(n, _)| n);
    model.comments = lines.iter().map(|(_, s)| (*s).to_owned()).collect();
    match keys.get(0) {
        Some(kv) => {
            if let Some(n) = info_uint(cx, kv, u16::MAX as u64, "Comments") {
                let numbered_ok = lines.iter().enumerate().all(|(i, &(k, _))| k == i as u32 + 1);
                if n as usize != lines.len() || !numbered_ok {
                    let d = cx.emit(
                        codes::E0503,
                        Some(kv.value_span(&cx.src.text)),
                        format!(
                            "[Comments] says Lines={n} but has {} lines numbered {}",
                            lines.len(),
                            describe_numbers(&lines)
                        ),
                    );
                    d.hint = Some(
                        format!("number the lines Line1..Line{} and set Lines={}", lines.len(), lines.len()).into(),
                    );
                }
            }
        }
        None if !lines.is_empty() => {
            cx.emit(codes::E0505, Some(sec.name_span), "[Comments] lacks `Lines`").hint =
                Some(format!("add `Lines={}`", lines.len()).into());
        }
        None => {}
    }
}

fn describe_numbers(lines: &[(u32, &str)]) -> String {
    match (lines.first(), lines.last()) {
        (Some(a), Some(b)) => format!("{}..{}", a.0, b.0),
        _ => "none".to_owned(),
    }
}

/// Lowers the information sections and keeps unknown sections.
pub(crate) fn lower_info(secs: &Sections<'_>, model: &mut Model, cx: &mut Ctx<'_>) {
    let mut have_file_info = false;
    let mut have_device_info = false;
    for sec in &secs.list {
        match sec.kind {
            Kind::FileInfo => {
                have_file_info = true;
                model.file_info = lower_file_info(cx, sec);
            }
            Kind::DeviceInfo => {
                have_device_info = true;
                model.device_info = lower_device_info(cx, sec);
            }
            Kind::Commissioning => model.commissioning = Some(lower_commissioning(cx, sec)),
            Kind::DummyUsage => lower_dummy_usage(cx, sec, model),
            Kind::Comments => lower_comments(cx, sec, model),
            Kind::Unknown => {
                cx.emit(
                    codes::E0101,
                    Some(sec.name_span),
                    format!("section [{}] is not a CiA 306 section; it is kept as written", sec.name),
                );
                // A key set again (in the section or in a repeat of it) keeps its first place
                // with the later value, as in every other section.
                let mut entries: Vec<(String, String)> = Vec::with_capacity(sec.entries.len());
                let mut seen: std::collections::HashMap<String, (usize, &Kv<'_>)> = std::collections::HashMap::new();
                for kv in sec.entries {
                    match seen.entry(kv.key().to_ascii_lowercase()) {
                        std::collections::hash_map::Entry::Occupied(e) => {
                            let (i, first) = *e.get();
                            report_duplicate(cx, first, kv, Crumbs::default());
                            entries[i] = owned(kv);
                        }
                        std::collections::hash_map::Entry::Vacant(e) => {
                            e.insert((entries.len(), kv));
                            entries.push(owned(kv));
                        }
                    }
                }
                model.extra_sections.push(ExtraSection { name: sec.name.to_owned(), entries });
            }
            _ => {}
        }
    }
    if !have_file_info {
        cx.emit(codes::E0502, None, "the file has no [FileInfo] section").hint =
            Some("add [FileInfo] with FileName, FileVersion, FileRevision and EDSVersion=4.0".into());
    }
    if !have_device_info {
        cx.emit(codes::E0502, None, "the file has no [DeviceInfo] section").hint =
            Some("add [DeviceInfo] with VendorName, ProductName, the BaudRate_ keys and the PDO counts".into());
    }
}

/// What the object lists say.
///
/// Each object of a file is looked up in them (its category, and whether it is listed): a bit
/// per index answers whether ([`IndexSet`]), and the category is the one CiA 306 expects
/// ([`expected_category`]) unless the object is listed elsewhere (each such entry is reported,
/// E0406, and few files have any), so that no look-up hashes.
#[derive(Default)]
pub(crate) struct Lists {
    /// Which of the three lists exist (Mandatory, Optional, Manufacturer).
    pub present: [bool; 3],
    /// Each listed index, once, with the list that names it first and the span of that entry,
    /// in the order the lists are read.
    pub listed: Vec<(u16, Category, Span)>,
    /// The listed indices.
    set: IndexSet,
    /// The listed indices whose list is not the one [`expected_category`] gives, with theirs,
    /// sorted by index (a file may misplace thousands: found by a binary search).
    misplaced: Vec<(u16, Category)>,
}

impl Lists {
    /// Whether a list names `index`.
    #[inline]
    pub fn contains(&self, index: u16) -> bool {
        self.set.contains(index)
    }

    /// The list that names `index` first, if any.
    pub fn category(&self, index: u16) -> Option<Category> {
        if !self.contains(index) {
            return None;
        }
        if self.misplaced.is_empty() {
            return Some(expected_category(index));
        }
        Some(match self.misplaced.binary_search_by_key(&index, |&(i, _)| i) {
            Ok(at) => self.misplaced[at].1,
            Err(_) => expected_category(index),
        })
    }

    /// The set of indices, emptied, for the next file's lists.
    pub fn into_set(mut self) -> IndexSet {
        self.set.clear(self.listed.iter().map(|&(i, _, _)| i));
        self.set
    }
}

/// A set of object indices, a bit each, in blocks of 256 indices (the indices that share their
/// high byte) made as the set needs them: a file lists a few hundred objects in a few dozen such
/// blocks, so that the set is a kilobyte or two, on pages in use anyway (a bit for each of the
/// 65,536 indices, 8 KiB kept from file to file, cost the run two fresh pages and displaced
/// other blocks: four to seven page faults more than the hash map it replaces). Kept from one file to
/// the next ([`Lists::into_set`]) and emptied by the indices put in it, not by zeroing it.
#[derive(Default)]
pub(crate) struct IndexSet {
    /// For each high byte, the number of its block plus one (0: none); empty while no index was
    /// ever put in.
    top: Vec<u16>,
    /// The blocks of 256 bits.
    blocks: Vec<[u64; 4]>,
}

impl IndexSet {
    /// Whether `index` is in the set.
    #[inline]
    pub fn contains(&self, index: u16) -> bool {
        let (hi, lo) = ((index >> 8) as usize, (index & 0xFF) as usize);
        match self.top.get(hi) {
            Some(&b) if b != 0 => self.blocks[b as usize - 1][lo / 64] >> (lo % 64) & 1 != 0,
            _ => false,
        }
    }

    /// Puts `index` in the set; whether it was in it before.
    #[inline]
    pub fn insert(&mut self, index: u16) -> bool {
        if self.top.is_empty() {
            self.top = vec![0; 256];
        }
        let (hi, lo) = ((index >> 8) as usize, (index & 0xFF) as usize);
        if self.top[hi] == 0 {
            self.blocks.push([0; 4]);
            self.top[hi] = self.blocks.len() as u16;
        }
        let word = &mut self.blocks[self.top[hi] as usize - 1][lo / 64];
        let bit = 1u64 << (lo % 64);
        let before = *word & bit != 0;
        *word |= bit;
        before
    }

    /// Empties the set, given (at least) every index in it.
    pub fn clear(&mut self, indices: impl Iterator<Item = u16>) {
        if !self.top.is_empty() {
            for index in indices {
                self.top[(index >> 8) as usize] = 0;
            }
        }
        debug_assert!(self.top.iter().all(|&b| b == 0));
        self.blocks.clear();
    }
}

pub(crate) fn category_slot(c: Category) -> usize {
    match c {
        Category::Mandatory => 0,
        Category::Optional => 1,
        Category::Manufacturer => 2,
    }
}

pub(crate) fn list_name(c: Category) -> &'static str {
    match c {
        Category::Mandatory => "MandatoryObjects",
        Category::Optional => "OptionalObjects",
        Category::Manufacturer => "ManufacturerObjects",
    }
}

/// The list an index belongs in by CiA 306: the mandatory objects (device type, error
/// register, identity), the manufacturer-specific area, the rest optional. (Decided on the
/// number, as `Index::role` places these; `expected_category_follows_the_roles` holds the two
/// together for every index.)
pub(crate) fn expected_category(index: u16) -> Category {
    match index {
        0x1000 | 0x1001 | 0x1018 => Category::Mandatory,
        0x2000..=0x5FFF => Category::Manufacturer,
        _ => Category::Optional,
    }
}

/// Reads the three object lists, into `set` (emptied; an earlier file's, from
/// [`Lists::into_set`], or a new one).
pub(crate) fn lower_object_lists(secs: &Sections<'_>, cx: &mut Ctx<'_>, set: IndexSet) -> Lists {
    let mut lists = Lists::default();
    let listed: usize = [Category::Mandatory, Category::Optional, Category::Manufacturer]
        .into_iter()
        .filter_map(|c| secs.get(Kind::List(c)))
        .map(|s| s.entries.len())
        .sum();
    lists.listed.reserve(listed);
    lists.set = set;
    // (Keyed by `u32`, as the index of sections is: one instance of the map's code for both.)
    let mut at: Option<FastMap<u32, u32>> = None;
    for cat in [Category::Mandatory, Category::Optional, Category::Manufacturer] {
        let Some(sec) = secs.get(Kind::List(cat)) else { continue };
        lists.present[category_slot(cat)] = true;
        let name = list_name(cat);
        // A constant, so that the key set is built when compiling, not on every call.
        const SUPPORTED_OBJECTS: KeySet<1> = KeySet::new(["SupportedObjects"]);
        let keys = match_keys(cx, sec, &SUPPORTED_OBJECTS, Crumbs::default(), false);
        // The entries' numbers, as long as they are 1, 2, 3, ... in order (as lists write
        // them) only counted; from the first out of order on, collected.
        let mut count = 0u32;
        let mut numbers: Option<Vec<u32>> = None;
        for kv in &keys.unknown {
            let Some(n) = list_number(kv.key()) else {
                let d = cx.emit(
                    codes::E0404,
                    Some(kv.key_span(&cx.src.text)),
                    format!("[{name}] entry `{}` is not numbered (ignored)", kv.key()),
                );
                d.hint = Some("list entries are `1=0x1000`, `2=0x1001`, ...".into());
                continue;
            };
            // The plain forms (`0x1000`) need neither the general number reader nor its list of
            // remarks (which this list does not report).
            // `0x1000`, four hex digits, above all.
            let plain = match kv.value().as_bytes() {
                &[b'0', b'x' | b'X', a, b, c, d] => {
                    crate::value::hex4_value([a, b, c, d]).map(|v| (v as u64, Radix::Hex))
                }
                _ => None,
            };
            let parsed = match plain.or_else(|| crate::value::parse_plain_uint(kv.value())) {
                Some((v, radix)) => Ok(crate::value::ParsedInt { value: v as i128, radix, negative: false }),
                None => parse_int(kv.value(), &mut Vec::new()),
            };
            let index = match parsed {
                Ok(p) if (0..=0xFFFF).contains(&p.value) => {
                    if p.radix != crate::model::Radix::Hex {
                        let d = cx.emit(
                            codes::E0404,
                            Some(kv.value_span(&cx.src.text)),
                            format!(
                                "[{name}] entry {n}=`{}` is not a 0x-prefixed index; read as 0x{:04X}",
                                kv.value(),
                                p.value
                            ),
                        );
                        d.hint = Some(format!("write `{n}=0x{:04X}`", p.value).into());
                    }
                    p.value as u16
                }
                _ => {
                    let d = cx.emit(
                        codes::E0404,
                        Some(kv.value_span(&cx.src.text)),
                        format!("[{name}] entry {n}=`{}` is not an object index (ignored)", kv.value()),
                    );
                    d.hint = Some("write the index as 0x1234".into());
                    continue;
                }
            };
            count += 1;
            match &mut numbers {
                None if n == count => {}
                None => numbers = Some((1..count).chain([n]).collect()),
                Some(numbers) => numbers.push(n),
            }
            if lists.set.insert(index) {
                // A repeat (rare): its first entry is found in a map of where each index is in
                // `listed`, made at the file's first repeat (a file of many repeats is not
                // searched for each).
                let listed = &lists.listed;
                let at = at.get_or_insert_with(|| {
                    let mut at = FastMap::with_capacity_and_hasher(listed.len(), Default::default());
                    at.extend(listed.iter().enumerate().map(|(n, &(i, _, _))| (i as u32, n as u32)));
                    at
                });
                if let Some(&(_, prev_cat, prev_span)) = at.get(&(index as u32)).map(|&n| &listed[n as usize]) {
                    let first = cx.src.line_col(prev_span.start);
                    let d = cx.emit(
                        codes::E0405,
                        Some(kv.value_span(&cx.src.text)),
                        format!(
                            "object 0x{index:04X} is listed again (first in [{}] at line {})",
                            list_name(prev_cat),
                            first.line
                        ),
                    );
                    d.hint = Some("list every object once".into());
                }
                continue;
            }
            let want = expected_category(index);
            if want != cat {
                let d = cx.emit(
                    codes::E0406,
                    Some(kv.value_span(&cx.src.text)),
                    format!("object 0x{index:04X} is listed in [{name}] but belongs in [{}]", list_name(want)),
                );
                d.hint = Some(format!("move it to [{}]", list_name(want)).into());
                lists.misplaced.push((index, cat));
            }
            if let Some(at) = &mut at {
                at.insert(index as u32, lists.listed.len() as u32);
            }
            lists.listed.push((index, cat, kv.value_span(&cx.src.text)));
        }
        let numbers = match numbers {
            Some(mut numbers) => {
                numbers.sort_unstable();
                numbers
            }
            None => Vec::new(),
        };
        // (Counted in order: 1..=count.)
        let consecutive = numbers.is_empty() || numbers.iter().enumerate().all(|(i, &n)| n == i as u32 + 1);
        let listed_count = count as usize;
        match keys.get(0) {
            Some(kv) => {
                let mut q = Vec::new();
                match parse_int(kv.value(), &mut q) {
                    Ok(p) if p.value == listed_count as i128 && consecutive => {}
                    Ok(p) => {
                        let d = cx.emit(
                            codes::E0403,
                            Some(kv.value_span(&cx.src.text)),
                            format!(
                                "[{name}] says SupportedObjects={} but lists {} objects{}",
                                p.value,
                                listed_count,
                                if consecutive {
                                    String::new()
                                } else {
                                    format!(" numbered {}", number_ranges(&numbers))
                                }
                            ),
                        );
                        d.hint = Some(
                            format!("number the entries 1..{n} and set SupportedObjects={n}", n = listed_count).into(),
                        );
                    }
                    Err(_) => {
                        cx.emit(
                            codes::E0403,
                            Some(kv.value_span(&cx.src.text)),
                            format!("[{name}] SupportedObjects=`{}` is not a number", kv.value()),
                        );
                    }
                }
            }
            None => {
                let d = cx.emit(codes::E0403, Some(sec.name_span), format!("[{name}] lacks `SupportedObjects`"));
                d.hint = Some(format!("add `SupportedObjects={}`", listed_count).into());
            }
        }
    }
    // (Each index once: no two entries with one index.)
    if lists.misplaced.len() > 1 {
        lists.misplaced.sort_unstable_by_key(|&(i, _)| i);
    }
    lists
}

/// The number of an object list's entry key, as `str::parse::<u32>` reads it (digits, with an
/// optional `+`); the commonest keys, up to nine digits, without the general parser.
#[inline]
fn list_number(key: &str) -> Option<u32> {
    let b = key.as_bytes();
    if b.is_empty() || b.len() > 9 {
        return key.parse().ok();
    }
    let mut v = 0u32;
    for &c in b {
        let d = c.wrapping_sub(b'0');
        if d > 9 {
            return key.parse().ok();
        }
        v = v * 10 + d as u32;
    }
    Some(v)
}

fn number_ranges(ns: &[u32]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < ns.len() {
        let mut j = i;
        while j + 1 < ns.len() && ns[j + 1] == ns[j] + 1 {
            j += 1;
        }
        parts.push(if i == j { ns[i].to_string() } else { format!("{}..{}", ns[i], ns[j]) });
        i = j + 1;
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Index, Role};

    #[test]
    fn dates_and_times() {
        assert!(is_date("01-31-2024"));
        assert!(!is_date("2024-01-31"));
        assert!(is_time("9:05AM"));
        assert!(is_time("12:59pm"));
        assert!(!is_time("20:31PM"));
        assert!(!is_time("10:3AM"));
    }

    #[test]
    fn expected_category_follows_the_roles() {
        for i in 0..=u16::MAX {
            let by_role = match Index(i).role() {
                Role::DeviceType | Role::ErrorRegister | Role::Identity => Category::Mandatory,
                Role::ManufacturerSpecific => Category::Manufacturer,
                _ => Category::Optional,
            };
            assert_eq!(expected_category(i), by_role, "{i:#06x}");
        }
    }

    #[test]
    fn list_numbers_read_as_parse_does() {
        for key in [
            "",
            "0",
            "1",
            "01",
            "+1",
            "-1",
            "+",
            "1+",
            " 1",
            "1 ",
            "a",
            "123456789",
            "999999999",
            "1000000000",
            "4294967295",
            "4294967296",
            "04294967295",
            "+4294967295",
            "0000000000001",
            "1\u{e9}",
            "\u{661}",
        ] {
            assert_eq!(list_number(key), key.parse::<u32>().ok(), "{key:?}");
        }
        for n in (0..100_000u32).chain([u32::MAX - 1, u32::MAX, 999_999_999, 1_000_000_000]) {
            assert_eq!(list_number(&n.to_string()), Some(n));
            assert_eq!(list_number(&format!("{n:012}")), Some(n));
        }
    }

    proptest::proptest! {
        /// The set of indices holds what a `BTreeSet` holds, file after file (emptied by the
        /// indices put in it and reused).
        #[test]
        fn index_sets_hold_what_a_btree_set_holds(
            files in proptest::collection::vec(proptest::collection::vec(proptest::prop_oneof![
                proptest::num::u16::ANY,
                0x1000u16..0x1040,
                0x6000u16..0x6100,
            ], 0..200), 1..4),
        ) {
            let mut set = IndexSet::default();
            for indices in &files {
                let mut reference = std::collections::BTreeSet::new();
                for &i in indices {
                    proptest::prop_assert_eq!(set.insert(i), !reference.insert(i));
                }
                // Every index, against the reference as a table (a BTreeSet lookup per index,
                // 65,536 a file, made this test take 26 s).
                let mut member = vec![false; 1 << 16];
                for &i in &reference {
                    member[usize::from(i)] = true;
                }
                let wrong = (0..=u16::MAX).find(|&i| set.contains(i) != member[usize::from(i)]);
                proptest::prop_assert!(wrong.is_none(), "{:#06x}", wrong.unwrap_or(0));
                set.clear(reference.iter().copied());
                proptest::prop_assert!((0..=u16::MAX).all(|i| !set.contains(i)));
            }
        }

        /// What the lists say of each index (listed or not, in which list first; once each, in
        /// the order the lists are read) is what a map of the entries in that order says, in a
        /// reader's files one after the other, whatever the lists, their order in the file,
        /// repeated and misplaced entries.
        #[test]
        fn lists_say_what_their_entries_say(
            files in proptest::collection::vec(proptest::collection::vec(
                (0..3usize, proptest::prop_oneof![0x1000u16..0x1020, 0x2000u16..0x2008, 0x6000u16..0x6008, proptest::num::u16::ANY]),
                0..40), 1..4),
        ) {
            let cats = [Category::Mandatory, Category::Optional, Category::Manufacturer];
            let mut set = IndexSet::default();
            for entries in &files {
                // Each list in the order of its first entry, its entries numbered in order.
                let mut text = String::new();
                let mut order: Vec<usize> = Vec::new();
                for &(c, _) in entries {
                    if !order.contains(&c) {
                        order.push(c);
                    }
                }
                let mut reference: Vec<(u16, Category)> = Vec::new();
                for &c in [0, 1, 2].iter().filter(|c| order.contains(c)) {
                    for &(_, i) in entries.iter().filter(|&&(e, _)| e == c) {
                        if !reference.iter().any(|&(r, _)| r == i) {
                            reference.push((i, cats[c]));
                        }
                    }
                }
                // The line of each list's entries (lists in file order).
                let mut lines: Vec<Vec<u32>> = vec![Vec::new(); 3];
                let mut line = 1;
                for &c in &order {
                    let mine: Vec<u16> = entries.iter().filter(|&&(e, _)| e == c).map(|&(_, i)| i).collect();
                    text.push_str(&format!("[{}]\nSupportedObjects={}\n", list_name(cats[c]), mine.len()));
                    line += 2;
                    for (n, i) in mine.iter().enumerate() {
                        text.push_str(&format!("{}=0x{i:04X}\n", n + 1));
                        lines[c].push(line);
                        line += 1;
                    }
                }
                // Each repeat's report names the list and line of the index's first entry (lists
                // read in category order).
                let mut first: Vec<(u16, usize, u32)> = Vec::new();
                let mut want_repeats: Vec<String> = Vec::new();
                for c in [0, 1, 2] {
                    for (&(_, i), &l) in entries.iter().filter(|&&(e, _)| e == c).zip(&lines[c]) {
                        match first.iter().find(|&&(f, _, _)| f == i) {
                            Some(&(_, fc, fl)) => want_repeats.push(format!(
                                "object 0x{i:04X} is listed again (first in [{}] at line {fl})",
                                list_name(cats[fc])
                            )),
                            None => first.push((i, c, l)),
                        }
                    }
                }
                let doc = crate::ast::Document::lexed(crate::source::SourceFile::from_str("x.eds", text.as_str()));
                let mut cx = Ctx::new(&doc.source, crate::Strictness::Lenient);
                let mut collected = crate::lower::sections::collect(&doc, &mut cx, &mut Default::default());
                let secs = collected.sections();
                let lists = lower_object_lists(&secs, &mut cx, std::mem::take(&mut set));
                proptest::prop_assert_eq!(
                    lists.listed.iter().map(|&(i, c, _)| (i, c)).collect::<Vec<_>>(),
                    reference.clone()
                );
                for i in entries.iter().map(|&(_, i)| i).chain([0, 0x1000, 0x1018, 0x2000, 0xFFFF]) {
                    let want = reference.iter().find(|&&(r, _)| r == i).map(|&(_, c)| c);
                    proptest::prop_assert_eq!(lists.category(i), want, "{:#06x}", i);
                    proptest::prop_assert_eq!(lists.contains(i), want.is_some());
                }
                let repeats: Vec<String> =
                    cx.diags.iter().filter(|d| d.code == codes::E0405).map(|d| d.message.clone()).collect();
                proptest::prop_assert_eq!(repeats.len(), entries.len() - reference.len());
                proptest::prop_assert_eq!(repeats, want_repeats);
                set = lists.into_set();
            }
        }

        #[test]
        fn list_numbers_agree_with_parse(key in "[+-]?[0-9a ]{0,12}") {
            proptest::prop_assert_eq!(list_number(&key), key.parse::<u32>().ok());
        }
    }

    /// The canonical form is read as the general rules read it, and only it.
    #[test]
    fn baud_rates_read_as_the_general_rules_read_them() {
        let general = |key: &str| {
            key.get(..9).filter(|p| p.eq_ignore_ascii_case("BaudRate_")).and_then(|_| key[9..].parse::<u16>().ok())
        };
        let mut keys: Vec<String> = (0..=10_000u32).map(|n| format!("BaudRate_{n}")).collect();
        keys.extend(
            ["BaudRate_", "BaudRate_01", "BaudRate_+5", "BaudRate_-5", "baudrate_10", "BaudRate_1 ", "BaudRate_65535"]
                .map(String::from),
        );
        keys.extend(
            ["BaudRate_65536", "BaudRate_1a", "BaudRate_\u{661}", "Baudrate_10", "BaudRate10", "BaudRate_0000"]
                .map(String::from),
        );
        for key in &keys {
            if let Some(r) = canonical_baud_rate(key) {
                assert_eq!(Some(r), general(key), "{key:?}");
                assert_eq!(format!("BaudRate_{r}"), *key, "{key:?}");
            }
        }
        // Every rate up to 9999 kbit/s written as CiA 306 writes it takes the short way.
        for n in 0..=9999u16 {
            assert_eq!(canonical_baud_rate(&format!("BaudRate_{n}")), Some(n));
        }
    }

    /// `dummy_type` reads what `str` slicing and `u16::from_str_radix` read.
    #[test]
    fn dummy_types_read_as_the_general_rules_read_them() {
        let general = |key: &str| {
            key.get(..5).filter(|p| p.eq_ignore_ascii_case("Dummy")).and_then(|_| {
                let digits = &key[5..];
                (digits.len() == 4 && digits.bytes().all(|b| b.is_ascii_hexdigit()))
                    .then(|| u16::from_str_radix(digits, 16).ok())
                    .flatten()
            })
        };
        let mut keys: Vec<String> = (0..=0xFFFFu32).map(|n| format!("Dummy{n:04X}")).collect();
        keys.extend((0..0x100u32).map(|n| format!("dUMMY{n:04x}")));
        for b in (0..0x80u8).map(|b| (b as char).to_string()).chain(["\u{e9}".into(), "\u{661}".into()]) {
            for at in 0..9 {
                let mut key: Vec<String> = "Dummy0007".chars().map(String::from).collect();
                key[at] = b.clone();
                keys.push(key.concat());
            }
        }
        keys.extend(["", "Dummy", "Dummy007", "Dummy00007", "Dummy+007", "Dummy\u{e9}07"].map(String::from));
        for key in &keys {
            assert_eq!(dummy_type(key), general(key), "{key:?}");
        }
    }

    #[test]
    fn ranges() {
        assert_eq!(number_ranges(&[1, 2, 3, 5, 7, 8]), "1..3, 5, 7..8");
    }
}
