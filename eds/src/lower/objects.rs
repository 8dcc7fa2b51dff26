//! Pass 3: object sections → [`Object`]s with typed [`Entry`]s.

use super::info::{Lists, expected_category};
use super::sections::{KeySet, Keys, Kind, Kv, Section, Sections, fill_keys, match_keys, reuse, with_room};
use super::{Crumbs, Ctx, otype};
use crate::codes;
use crate::model::{
    Access, DataType, Entry, EntryExtras, FileKind, Index, Model, Name, Object, ObjectMap, ObjectType, SourceRef,
    SubIndex, SubMap, Value,
};
use crate::value::{self, Quirk, ValueError};

const OBJ_KEYS: KeySet<15> = KeySet::new([
    "ParameterName",
    "ObjectType",
    "DataType",
    "AccessType",
    "DefaultValue",
    "PDOMapping",
    "LowLimit",
    "HighLimit",
    "ParameterValue",
    "ObjFlags",
    "SubNumber",
    "CompactSubObj",
    "Denotation",
    "UploadFile",
    "DownloadFile",
]);
/// The keys of an object or sub-object section, matched.
type ObjKeys<'a> = Keys<'a, 15>;
const NR_OF_ENTRIES: KeySet<1> = KeySet::new(["NrOfEntries"]);
const OBJECT_LINKS: KeySet<1> = KeySet::new(["ObjectLinks"]);
const K_NAME: usize = 0;
const K_OTYPE: usize = 1;
const K_DTYPE: usize = 2;
const K_ACCESS: usize = 3;
const K_DEFAULT: usize = 4;
const K_PDO: usize = 5;
const K_LOW: usize = 6;
const K_HIGH: usize = 7;
const K_PVALUE: usize = 8;
const K_FLAGS: usize = 9;
const K_SUBNUM: usize = 10;
const K_COMPACT: usize = 11;
const K_DENOT: usize = 12;
const K_UPLOAD: usize = 13;
const K_DOWNLOAD: usize = 14;

/// Keys that describe a single value; on an ARRAY/RECORD section they only mean something with
/// CompactSubObj, and on a NULL object never.
const VALUE_KEYS: [usize; 9] = [K_DTYPE, K_ACCESS, K_DEFAULT, K_PDO, K_LOW, K_HIGH, K_PVALUE, K_UPLOAD, K_DOWNLOAD];

/// Keeps the value keys of an object that has no single value (kept as written, with a note),
/// and its Denotation (meaningful for any object, but the model has no field for it).
fn keep_entry_keys(
    cx: &mut Ctx<'_>,
    keys: &ObjKeys<'_>,
    t: ObjectType,
    ctx: Crumbs<'_>,
    extra: &mut Vec<(String, String)>,
) {
    for kv in VALUE_KEYS.iter().chain(&[K_DENOT]).filter_map(|&i| keys.get(i)) {
        if !kv.key().eq_ignore_ascii_case("Denotation") {
            let what = if t == ObjectType::Null { "" } else { " without CompactSubObj" };
            let d = cx.emit(
                codes::E0217,
                Some(kv.key_span(&cx.src.text)),
                format!("{} has no meaning for object type {}{what} (kept)", kv.key(), otype(t)),
            );
            d.context = ctx.to_vec();
        }
        extra.push(owned(kv));
    }
}

fn owned(kv: &Kv<'_>) -> (String, String) {
    (kv.key().to_owned(), kv.value().to_owned())
}

fn source_ref(sec: &Section<'_>) -> SourceRef {
    SourceRef { line: sec.at.line, col: sec.at.col, span: sec.name_span }
}

/// The text before an inline `;` or `#` comment, if there is one.
fn before_comment(v: &str) -> Option<&str> {
    v.find([';', '#']).map(|i| v[..i].trim_end())
}

/// `read` of a value's text; when that fails, [`retry_before_comment`]. The one rule for every
/// key read this way: a value that cannot be read as written, but can once an inline comment is
/// cut off, is read so, with a warning (E0008).
fn read_before_comment<T, E>(
    cx: &mut Ctx<'_>,
    kv: &Kv<'_>,
    context: Crumbs<'_>,
    quirks: &mut Vec<Quirk>,
    mut read: impl FnMut(&str, &mut Vec<Quirk>) -> Result<T, E>,
) -> Result<T, E> {
    read(kv.value(), quirks).or_else(|e| retry_before_comment(cx, kv, context, quirks, e, read))
}

/// After `read` of a value's text failed with `first`: `read` of the text before its inline
/// comment, if it has one and that reads (reported as E0008), otherwise `first`. `quirks` are
/// then those of the reading that counts.
fn retry_before_comment<T, E>(
    cx: &mut Ctx<'_>,
    kv: &Kv<'_>,
    context: Crumbs<'_>,
    quirks: &mut Vec<Quirk>,
    first: E,
    mut read: impl FnMut(&str, &mut Vec<Quirk>) -> Result<T, E>,
) -> Result<T, E> {
    let Some(head) = before_comment(kv.value()) else { return Err(first) };
    quirks.clear();
    match read(head, quirks) {
        Ok(v) => {
            inline_comment(cx, kv, head, context);
            Ok(v)
        }
        Err(_) => Err(first),
    }
}

/// Reads a plain unsigned integer key (ObjectType, DataType, SubNumber, ...). An inline comment
/// is removed with a warning. Returns `Err(text)` when unreadable.
#[inline]
fn uint_key(cx: &mut Ctx<'_>, kv: &Kv<'_>, max: u32, context: Crumbs<'_>) -> Result<u32, ()> {
    match value::parse_plain_uint(kv.value()) {
        Some((v, _)) => {
            if v <= max as u64 {
                Ok(v as u32)
            } else {
                Err(())
            }
        }
        None => uint_key_general(cx, kv, max, context),
    }
}

/// [`uint_key`] for the forms that are not plain (kept out of line: most values are plain).
#[inline(never)]
fn uint_key_general(cx: &mut Ctx<'_>, kv: &Kv<'_>, max: u32, context: Crumbs<'_>) -> Result<u32, ()> {
    cx.with_quirks(|cx, quirks| uint_key_quirks(cx, kv, max, context, quirks))
}

/// [`uint_key_general`], its quirks found in `quirks` (empty).
fn uint_key_quirks(
    cx: &mut Ctx<'_>,
    kv: &Kv<'_>,
    max: u32,
    context: Crumbs<'_>,
    quirks: &mut Vec<value::Quirk>,
) -> Result<u32, ()> {
    match read_before_comment(cx, kv, context, quirks, value::parse_int) {
        Ok(p) if p.value >= 0 && p.value <= max as i128 => {
            report_quirks(cx, kv, quirks, context);
            Ok(p.value as u32)
        }
        _ => Err(()),
    }
}

fn inline_comment(cx: &mut Ctx<'_>, kv: &Kv<'_>, head: &str, context: Crumbs<'_>) {
    let d = cx.emit(
        codes::E0008,
        Some(kv.value_span(&cx.src.text)),
        super::cat([kv.key(), " `", kv.value(), "` carries an inline comment; read as `", head, "`"]),
    );
    d.hint = Some("CiA 306 has no inline comments: put the comment on its own line, starting with `;`".into());
    d.context = context.to_vec();
}

fn report_quirks(cx: &mut Ctx<'_>, kv: &Kv<'_>, quirks: &[Quirk], context: Crumbs<'_>) {
    for q in quirks {
        let span = Some(kv.value_span(&cx.src.text));
        let text = kv.value();
        let (code, msg, hint) = match *q {
            Quirk::AmbiguousOctal { octal, decimal } => (
                codes::E0303,
                format!(
                    "{} `{text}` has a leading zero: CiA 306 reads it as octal ({octal}), not decimal ({decimal})",
                    kv.key()
                ),
                Some(format!(
                    "write `{decimal}` if decimal was meant, or `0x{octal:X}` if octal was meant; python-canopen cannot read `{text}` at all"
                ).into()),
            ),
            Quirk::LeadingZeros => (
                codes::E0305,
                format!("{} `{text}` has leading zeros (octal by CiA 306; the same value in decimal)", kv.key()),
                Some("drop the leading zeros; python-canopen cannot read numbers written with them".into()),
            ),
            Quirk::DecimalWithLeadingZero => (
                codes::E0304,
                format!(
                    "{} `{text}` has a leading zero but digits 8 or 9, so it is not octal; read as decimal",
                    kv.key()
                ),
                Some("drop the leading zero".into()),
            ),
            Quirk::HexBitPattern => {
                (codes::E0309, format!("{} `{text}` is read as a two's complement bit pattern", kv.key()), None)
            }
            Quirk::RealBitPattern => {
                (codes::E0310, format!("{} `{text}` is read as an IEEE 754 bit pattern", kv.key()), None)
            }
            Quirk::BooleanWord => (
                codes::E0311,
                format!("{} `{text}` is a word; CiA 306 writes BOOLEAN values as 0 or 1", kv.key()),
                Some("write 0 or 1".into()),
            ),
            Quirk::DomainNotHex => {
                (codes::E0312, format!("{} `{text}` of a DOMAIN is not hex bytes; kept as text", kv.key()), None)
            }
            Quirk::EmptyNumeric => continue,
            Quirk::SpacedNumber => (
                codes::E0314,
                format!("{} `{text}` has white space inside the number", kv.key()),
                Some("remove the space".into()),
            ),
            Quirk::TimePair => (codes::E0316, format!("{} `{text}` is written as `days ms`", kv.key()), None),
            Quirk::CSuffix => (
                codes::E0317,
                format!("{} `{text}` carries a C literal suffix", kv.key()),
                Some("remove the suffix (U, L, LL, f): CiA 306 numbers have none".into()),
            ),
        };
        let d = cx.emit(code, span, msg);
        d.hint = hint;
        d.context = context.to_vec();
    }
}

fn value_error_hint(e: &ValueError, ty: DataType) -> String {
    match e {
        ValueError::NotANumber(_) | ValueError::TooLarge(_) => {
            format!("a {} value is a decimal number, a 0x-prefixed hexadecimal number or `$NODEID+number`", ty.name())
        }
        ValueError::BadNodeIdExpr(_) => "write `$NODEID+0x180` or `0x180+$NODEID`".to_owned(),
        ValueError::NodeIdNotAllowed(_) => "$NODEID may only be used with integer types".to_owned(),
        ValueError::NotHexBytes(_) => "write the bytes as pairs of hex digits, e.g. `0A1B2C`".to_owned(),
        ValueError::NotAReal(_) => "write a decimal number such as `1.5` or `-2e3`".to_owned(),
        ValueError::RealPatternTooWide(..) => {
            format!("a {} bit pattern has at most {} hex digits", ty.name(), ty.bits().unwrap_or(0) / 4)
        }
    }
}

/// The commonest value: a plain unsigned number ([`value::parse_plain_uint`]) of an integer
/// type (or BOOLEAN) that is at most the type's largest positive value. [`value::parse_value`]
/// reads it as this value with no remark and [`value::check_range`] accepts it, so it is taken
/// as it is, without them; `None` for anything else (then they decide).
#[inline]
fn plain_int_value(text: &str, ty: DataType) -> Option<Value> {
    let max: u64 = match ty {
        DataType::Boolean => 1,
        DataType::Integer8 => 0x7F,
        DataType::Integer16 => 0x7FFF,
        DataType::Integer24 => 0x7F_FFFF,
        DataType::Integer32 => 0x7FFF_FFFF,
        DataType::Integer40 => 0x7F_FFFF_FFFF,
        DataType::Integer48 => 0x7FFF_FFFF_FFFF,
        DataType::Integer56 => 0x7F_FFFF_FFFF_FFFF,
        DataType::Integer64 => 0x7FFF_FFFF_FFFF_FFFF,
        DataType::Unsigned8 => 0xFF,
        DataType::Unsigned16 => 0xFFFF,
        DataType::Unsigned24 => 0xFF_FFFF,
        DataType::Unsigned32 => 0xFFFF_FFFF,
        DataType::Unsigned40 => 0xFF_FFFF_FFFF,
        DataType::Unsigned48 => 0xFFFF_FFFF_FFFF,
        DataType::Unsigned56 => 0xFF_FFFF_FFFF_FFFF,
        DataType::Unsigned64 => u64::MAX,
        _ => return None,
    };
    let (v, radix) = value::parse_plain_uint(text)?;
    (v <= max).then_some(Value::Int { value: v as i128, radix })
}

/// Reads a value key. `Ok(None)` means no value (empty); `Err(())` means the text could not be
/// read (already reported; the caller keeps it as written). The commonest value, a plain
/// number, is read where the value is wanted, without a call.
#[inline(always)]
fn value_key(cx: &mut Ctx<'_>, kv: &Kv<'_>, ty: DataType, context: Crumbs<'_>) -> Result<Option<Value>, ()> {
    if let Some(v) = plain_int_value(kv.value(), ty) {
        return Ok(Some(v));
    }
    // An empty value of any type but the strings is no value, with no remark (the general
    // rules' one quirk for it, EmptyNumeric, is not reported here; E0308 is the caller's).
    if kv.value().is_empty() && !matches!(ty, DataType::VisibleString | DataType::UnicodeString | DataType::OctetString)
    {
        return Ok(None);
    }
    value_key_other(cx, kv, ty, context)
}

/// [`value_key`] for a value that is not a plain number (kept out of line).
#[inline(never)]
fn value_key_other(cx: &mut Ctx<'_>, kv: &Kv<'_>, ty: DataType, context: Crumbs<'_>) -> Result<Option<Value>, ()> {
    cx.with_quirks(|cx, quirks| value_key_general(cx, kv, ty, context, quirks))
}

/// [`value_key`] for a value that is not a plain number, its quirks found in `quirks` (empty).
fn value_key_general(
    cx: &mut Ctx<'_>,
    kv: &Kv<'_>,
    ty: DataType,
    context: Crumbs<'_>,
    quirks: &mut Vec<value::Quirk>,
) -> Result<Option<Value>, ()> {
    let mut parsed = value::parse_value_into(kv.value(), ty, quirks);
    if let DataType::Other(_) = ty {
        // The type is not known here: keep what cannot be read as a number as text.
        return Ok(match parsed {
            Ok(v) => v,
            Err(_) => Some(Value::Text(kv.value().to_owned())),
        });
    }
    // (A string's text is its value, comment characters included.)
    let string_type = matches!(ty, DataType::VisibleString | DataType::UnicodeString | DataType::OctetString);
    if !string_type {
        parsed = parsed
            .or_else(|e| retry_before_comment(cx, kv, context, quirks, e, |t, q| value::parse_value_into(t, ty, q)));
    }
    match parsed {
        Ok(p) => {
            if !quirks.is_empty() {
                report_quirks(cx, kv, quirks, context);
            }
            if let Some(v) = &p
                && let Err(why) = value::check_range(v, ty)
            {
                let d = cx.emit(
                    codes::E0302,
                    Some(kv.value_span(&cx.src.text)),
                    format!("{} `{}`: {why}", kv.key(), kv.value()),
                );
                d.context = context.to_vec();
                if let (Some(bits), Some(x)) = (ty.bits(), v.as_int())
                    && ty.is_unsigned()
                    && x < 0
                    && x >= -(1i128 << (bits - 1))
                {
                    d.hint = Some(
                        format!("for a negative value use a signed type, or write 0x{:X}", x + (1i128 << bits)).into(),
                    );
                }
            }
            Ok(p)
        }
        Err(e) => {
            let d = cx.emit(
                codes::E0301,
                Some(kv.value_span(&cx.src.text)),
                format!("{} `{}` cannot be read as {}: {e}", kv.key(), kv.value(), ty.name()),
            );
            d.hint = Some(value_error_hint(&e, ty).into());
            d.context = context.to_vec();
            Err(())
        }
    }
}

/// Parses `AccessType`, accepting common non-standard spellings with a warning.
fn access_key(cx: &mut Ctx<'_>, kv: &Kv<'_>, context: Crumbs<'_>) -> Access {
    let text = kv.value();
    // Upper or mixed case is common and harmless; CiA 306 is silent on case here.
    if let Ok(a) = read_before_comment(cx, kv, context, &mut Vec::new(), |t, _| Access::parse(t).ok_or(())) {
        return a;
    }
    let lower = text.trim().to_ascii_lowercase();
    let guess = match lower.as_str() {
        "r" | "read" | "readonly" | "read-only" | "read_only" => Some(Access::Ro),
        "w" | "write" | "writeonly" | "write-only" | "write_only" => Some(Access::Wo),
        "readwrite" | "read-write" | "read_write" | "r/w" | "wr" => Some(Access::Rw),
        "c" => Some(Access::Const),
        _ => None,
    };
    let d = cx.emit(
        codes::E0207,
        Some(kv.value_span(&cx.src.text)),
        match guess {
            Some(a) => {
                super::cat(["AccessType `", kv.value(), "` is not a CiA 306 access type; read as `", a.as_str(), "`"])
            }
            None => super::cat(["AccessType `", kv.value(), "` is not a CiA 306 access type; `ro` assumed"]),
        },
    );
    d.hint = Some(
        match guess {
            Some(a) => super::cat(["write `", a.as_str(), "` (one of ro, wo, rw, rwr, rww, const)"]),
            None => "write one of ro, wo, rw, rwr, rww, const".to_owned(),
        }
        .into(),
    );
    d.context = context.to_vec();
    guess.unwrap_or(Access::Ro)
}

/// Defaults an entry takes when its section does not say (CiA 306 table of keywords).
#[derive(Clone, Copy, Default)]
struct EntryDefaults {
    data_type: Option<DataType>,
    access: Option<Access>,
}

/// Reads the entry keys of one section.
#[derive(Clone, Copy)]
struct EntryBuilder<'c> {
    is_dcf: bool,
    /// The sections, to look up the types the file defines.
    secs: &'c Sections<'c>,
    /// Building the template of CompactSubObj entries from an ARRAY section, where SubNumber
    /// and CompactSubObj are expected.
    compact_template: bool,
}

impl EntryBuilder<'_> {
    #[allow(clippy::too_many_arguments)]
    fn build(
        &self,
        cx: &mut Ctx<'_>,
        sec: &Section<'_>,
        keys: &ObjKeys<'_>,
        sub: u8,
        name: Option<Name>,
        defaults: EntryDefaults,
        context: Crumbs<'_>,
    ) -> Option<Entry> {
        let mut extra: Vec<(String, String)> = Vec::new();
        let name = match name.or_else(|| keys.get(K_NAME).map(|kv| Name::from(kv.value()))) {
            Some(n) => n,
            None => {
                let d = cx.emit(codes::E0201, Some(sec.name_span), format!("[{}] lacks ParameterName", sec.name));
                d.hint = Some("add `ParameterName=...`".into());
                d.context = context.to_vec();
                Name::from(sec.name)
            }
        };
        let data_type = match keys.get(K_DTYPE) {
            Some(kv) => match uint_key(cx, kv, 0xFFFF, context) {
                Ok(code) => DataType::from_code(code as u16),
                Err(()) => {
                    let d = cx.emit(
                        codes::E0205,
                        Some(kv.value_span(&cx.src.text)),
                        format!("DataType `{}` is not a type index; the entry is skipped", kv.value()),
                    );
                    d.hint = Some("write the index of the type, e.g. `0x0007` for UNSIGNED32".into());
                    d.context = context.to_vec();
                    return None;
                }
            },
            None => match defaults.data_type {
                Some(t) => t,
                None => {
                    let d = cx.emit(
                        codes::E0204,
                        Some(sec.name_span),
                        format!("[{}] lacks DataType; the entry is skipped", sec.name),
                    );
                    d.hint = Some("add `DataType=0x0007` (or the index of the right type)".into());
                    d.context = context.to_vec();
                    return None;
                }
            },
        };
        if let DataType::Other(code) = data_type
            && self.secs.get(Kind::Object(code)).is_none()
            && !(0x20..=0x25).contains(&code)
            && let Some(kv) = keys.get(K_DTYPE)
        {
            let d = cx.emit(
                codes::E0215,
                Some(kv.value_span(&cx.src.text)),
                format!("DataType 0x{code:04X} is not a basic CiA 301 type and the file does not define it"),
            );
            d.hint = Some("values of this entry are kept as written".into());
            d.context = context.to_vec();
        }
        let access = match keys.get(K_ACCESS) {
            Some(kv) => access_key(cx, kv, context),
            None => match defaults.access {
                Some(a) => a,
                None => {
                    let d = cx.emit(
                        codes::E0206,
                        Some(sec.name_span),
                        format!("[{}] lacks AccessType; `ro` assumed", sec.name),
                    );
                    d.hint = Some("add `AccessType=ro` (or rw, wo, rwr, rww, const)".into());
                    d.context = context.to_vec();
                    Access::Ro
                }
            },
        };
        let pdo_mapping = match keys.get(K_PDO) {
            None => false,
            Some(kv) => match uint_key(cx, kv, u32::MAX, context) {
                Ok(0) => false,
                Ok(1) => true,
                other => {
                    let v = kv.value().trim();
                    let guess = if v.eq_ignore_ascii_case("true") {
                        true
                    } else if v.eq_ignore_ascii_case("false") {
                        false
                    } else {
                        other.is_ok_and(|n| n != 0)
                    };
                    let d = cx.emit(
                        codes::E0208,
                        Some(kv.value_span(&cx.src.text)),
                        format!("PDOMapping `{v}` is not 0 or 1; read as {}", guess as u8),
                    );
                    d.hint = Some("write 0 (not mappable) or 1 (mappable)".into());
                    d.context = context.to_vec();
                    guess
                }
            },
        };
        let val = |cx: &mut Ctx<'_>, i: usize, extra: &mut Vec<(String, String)>| -> Option<Value> {
            let kv = keys.get(i)?;
            match value_key(cx, kv, data_type, context) {
                Ok(v) => v,
                Err(()) => {
                    extra.push(owned(kv));
                    None
                }
            }
        };
        let default = val(cx, K_DEFAULT, &mut extra);
        let parameter_value = val(cx, K_PVALUE, &mut extra);
        let low_limit = val(cx, K_LOW, &mut extra);
        let high_limit = val(cx, K_HIGH, &mut extra);
        let empty_numeric = |kv: Option<&Kv<'_>>| kv.is_some_and(|kv| kv.value().is_empty()) && is_numeric(data_type);
        for i in [K_DEFAULT, K_PVALUE] {
            if empty_numeric(keys.get(i))
                && let Some(kv) = keys.get(i)
                && !cx.skips(codes::E0308)
            {
                let d = cx.emit(
                    codes::E0308,
                    Some(kv.value_span(&cx.src.text)),
                    super::cat([kv.key(), " of a ", data_type.name(), " is empty"]),
                );
                d.hint = Some(match kv.key() {
                    // (As CiA 306 spells the keys, which nearly every file does: no string to build.)
                    "DefaultValue" => "write a value or remove the `DefaultValue=` line".into(),
                    "ParameterValue" => "write a value or remove the `ParameterValue=` line".into(),
                    key => super::cat(["write a value or remove the `", key, "=` line"]).into(),
                });
                d.context = context.to_vec();
            }
        }
        if !self.is_dcf
            && let Some(kv) = keys.get(K_PVALUE)
        {
            let d = cx.emit(
                codes::E0315,
                Some(kv.key_span(&cx.src.text)),
                "ParameterValue in an EDS (it belongs in a DCF)",
            );
            d.hint = Some("a device's defaults go in DefaultValue".into());
            d.context = context.to_vec();
        }
        let obj_flags = keys.get(K_FLAGS).and_then(|kv| match uint_key(cx, kv, u32::MAX, context) {
            Ok(v) => Some(v),
            Err(()) => {
                let d = cx.emit(
                    codes::E0216,
                    Some(kv.value_span(&cx.src.text)),
                    format!("ObjFlags `{}` is not a number (kept as text)", kv.value()),
                );
                d.context = context.to_vec();
                extra.push(owned(kv));
                None
            }
        });
        for i in [K_SUBNUM, K_COMPACT] {
            if self.compact_template {
                break;
            }
            if let Some(kv) = keys.get(i) {
                let d = cx.emit(
                    codes::E0217,
                    Some(kv.key_span(&cx.src.text)),
                    format!("{} has no meaning on a single value (kept)", kv.key()),
                );
                d.context = context.to_vec();
                extra.push(owned(kv));
            }
        }
        if !keys.unknown.is_empty() {
            extra.extend(keys.unknown.iter().map(|kv| owned(kv)));
        }
        let (denotation, upload, download) = (keys.get(K_DENOT), keys.get(K_UPLOAD), keys.get(K_DOWNLOAD));
        // Most entries have none of these: then nothing is built for them.
        let any = parameter_value.is_some()
            || low_limit.is_some()
            || high_limit.is_some()
            || obj_flags.is_some()
            || denotation.is_some()
            || upload.is_some()
            || download.is_some()
            || !extra.is_empty();
        let extras = any.then(|| {
            Box::new(EntryExtras {
                parameter_value,
                low_limit,
                high_limit,
                obj_flags,
                denotation: denotation.map(|kv| kv.value().to_owned()),
                upload_file: upload.map(|kv| kv.value().to_owned()),
                download_file: download.map(|kv| kv.value().to_owned()),
                extra,
            })
        });
        let entry =
            Entry { sub: SubIndex(sub), name, data_type, access, pdo_mapping, default, extras, at: source_ref(sec) };
        check_entry(cx, &entry, keys, context);
        Some(entry)
    }
}

fn is_numeric(t: DataType) -> bool {
    t.int_range().is_some() || t.is_real() || matches!(t, DataType::TimeOfDay | DataType::TimeDifference)
}

/// A number to compare limits with (`None` for `$NODEID` values, text and bytes).
fn as_f64(v: &Value) -> Option<f64> {
    match *v {
        Value::Int { value, .. } => Some(value as f64),
        Value::Real(f) => Some(f),
        _ => None,
    }
}

fn cmp_values(a: &Value, b: &Value) -> Option<std::cmp::Ordering> {
    match (a, b) {
        (Value::Int { value: x, .. }, Value::Int { value: y, .. }) => Some(x.cmp(y)),
        (Value::NodeIdPlus { offset: x, .. }, Value::NodeIdPlus { offset: y, .. }) => Some(x.cmp(y)),
        _ => cmp_mixed(a, b),
    }
}

/// [`cmp_values`] for values of different kinds, compared as `f64` (kept out of line, so that
/// the common integer comparison does not convert both sides to `f64` on speculation).
#[inline(never)]
fn cmp_mixed(a: &Value, b: &Value) -> Option<std::cmp::Ordering> {
    as_f64(a)?.partial_cmp(&as_f64(b)?)
}

/// Checks within one entry: limits against each other and the values, PDOMapping against the
/// access type and the data type.
fn check_entry(cx: &mut Ctx<'_>, e: &Entry, keys: &ObjKeys<'_>, context: Crumbs<'_>) {
    let span_of = |i: usize| keys.get(i).map(|kv| kv.value_span(&cx.src.text));
    let (low_limit, high_limit) = (e.low_limit(), e.high_limit());
    // (Most entries have no limits: then none of the checks of limits can fire.)
    if low_limit.is_some() || high_limit.is_some() {
        if !is_numeric(e.data_type) {
            if let DataType::Other(_) = e.data_type {
            } else {
                let span = span_of(K_LOW).or(span_of(K_HIGH));
                let d =
                    cx.emit(codes::E0313, span, format!("limits on a {} entry have no meaning", e.data_type.name()));
                d.context = context.to_vec();
            }
        }
        if let (Some(lo), Some(hi)) = (low_limit, high_limit)
            && cmp_values(lo, hi) == Some(std::cmp::Ordering::Greater)
        {
            let d = cx.emit(
                codes::E0307,
                span_of(K_LOW),
                format!(
                    "LowLimit {} is greater than HighLimit {}",
                    value::format_value(lo, e.data_type),
                    value::format_value(hi, e.data_type)
                ),
            );
            d.hint = Some("swap the limits".into());
            d.context = context.to_vec();
            return;
        }
        for (i, v) in [(K_DEFAULT, e.default.as_ref()), (K_PVALUE, e.parameter_value())] {
            let Some(v) = v else { continue };
            let low = low_limit.filter(|lo| cmp_values(v, lo) == Some(std::cmp::Ordering::Less));
            let high = high_limit.filter(|hi| cmp_values(v, hi) == Some(std::cmp::Ordering::Greater));
            if let Some(bound) = low.or(high) {
                let key = OBJ_KEYS.names[i];
                let d = cx.emit(
                    codes::E0306,
                    span_of(i),
                    format!(
                        "{key} {} is {} the {} {}",
                        value::format_value(v, e.data_type),
                        if low.is_some() { "below" } else { "above" },
                        if low.is_some() { "LowLimit" } else { "HighLimit" },
                        value::format_value(bound, e.data_type)
                    ),
                );
                d.context = context.to_vec();
            }
        }
    }
    let span = span_of(K_PDO).or(span_of(K_ACCESS));
    if matches!(e.access, Access::Rwr | Access::Rww) && !e.pdo_mapping {
        let d = cx.emit(
            codes::E0610,
            span,
            format!(
                "AccessType {} says which PDO direction the entry is mapped in, but PDOMapping is 0",
                e.access.as_str()
            ),
        );
        d.hint = Some("set PDOMapping=1, or use AccessType=rw".into());
        d.context = context.to_vec();
    }
    if e.pdo_mapping && matches!(e.data_type, DataType::Domain) {
        let d = cx.emit(codes::E0610, span, "PDOMapping=1 on a DOMAIN, which cannot be mapped into a PDO");
        d.hint = Some("set PDOMapping=0".into());
        d.context = context.to_vec();
    }
}

/// Reads a `[xxxxName]`/`[xxxxValue]`/`[xxxxObjectLinks]` section: the count key and the
/// numbered entries (1-based, decimal).
fn numbered<'s, 'a>(
    cx: &mut Ctx<'_>,
    sec: &'s Section<'a>,
    count: &KeySet<1>,
    context: Crumbs<'_>,
) -> Vec<(u32, &'s Kv<'a>)> {
    let count_key = count.names[0];
    let keys = match_keys(cx, sec, count, context, false);
    let mut out = Vec::new();
    for kv in &keys.unknown {
        match kv.key().parse::<u32>() {
            Ok(n) => out.push((n, *kv)),
            Err(_) => {
                let d = cx.emit(
                    codes::E0214,
                    Some(kv.key_span(&cx.src.text)),
                    format!("[{}] entry `{}` is not numbered (ignored)", sec.name, kv.key()),
                );
                d.context = context.to_vec();
            }
        }
    }
    match keys.get(0) {
        Some(kv) => {
            if let Ok(n) = uint_key(cx, kv, u32::MAX, context) {
                if n as usize != out.len() {
                    let d = cx.emit(
                        codes::E0214,
                        Some(kv.value_span(&cx.src.text)),
                        format!("[{}] says {count_key}={n} but has {} entries", sec.name, out.len()),
                    );
                    d.hint = Some(format!("set {count_key}={}", out.len()).into());
                    d.context = context.to_vec();
                }
            } else {
                let d = cx.emit(
                    codes::E0214,
                    Some(kv.value_span(&cx.src.text)),
                    format!("{count_key} `{}` is not a number", kv.value()),
                );
                d.context = context.to_vec();
            }
        }
        None => {
            let d = cx.emit(codes::E0214, Some(sec.name_span), format!("[{}] lacks `{count_key}`", sec.name));
            d.hint = Some(format!("add `{count_key}={}`", out.len()).into());
            d.context = context.to_vec();
        }
    }
    out
}

/// Lowers every object section into `model.objects`.
pub(crate) fn lower_objects(secs: &Sections<'_>, lists: &Lists, model: &mut Model, cx: &mut Ctx<'_>) {
    // (The lists are made on the buffers of the last file's, with room for this file's sections
    // or for a file of the size the reader expects, whichever is more: see `pool`.)
    let lists_of = std::mem::take(&mut cx.pool.lists);
    let room = secs.list.len().max(cx.pool.room / 64 + 8);
    let mut objects: Vec<(u16, &Section<'_>)> = with_room(reuse(lists_of.objects), room);
    // Sub-object sections by object index, in file order for each index (the sort is stable).
    let mut subs: Vec<(u16, (u8, &Section<'_>))> = with_room(reuse(lists_of.subs), room);
    let mut orphans: Vec<&Section<'_>> = Vec::new();
    // The [xxxxName], [xxxxValue] and [xxxxObjectLinks] sections (0, 1, 2) by object index: few,
    // and most files have none. Each kind of section is in the list once, so an object finds its
    // own by one search of these, not by three look-ups in the index of all sections.
    let mut side: Vec<(u16, u8, &Section<'_>)> = Vec::new();
    for sec in &secs.list {
        match sec.kind {
            Kind::Object(i) => objects.push((i, sec)),
            Kind::Sub(i, s) => subs.push((i, (s, sec))),
            Kind::Names(i) | Kind::Values(i) | Kind::Links(i) => {
                let which = match sec.kind {
                    Kind::Names(_) => 0,
                    Kind::Values(_) => 1,
                    _ => 2,
                };
                side.push((i, which, sec));
                if secs.get(Kind::Object(i)).is_none() {
                    orphans.push(sec)
                }
            }
            _ => {}
        }
    }
    side.sort_unstable_by_key(|&(i, which, _)| (i, which));
    let mut object_indices: Vec<u16> = with_room(lists_of.object_indices, room);
    object_indices.extend(objects.iter().map(|&(i, _)| i));
    object_indices.sort_unstable();
    subs.sort_by_key(|&(i, _)| i);
    let mut sub_indices: Vec<u16> = with_room(lists_of.sub_indices, room);
    sub_indices.extend(subs.iter().map(|&(i, _)| i));
    let mut sub_sections: Vec<(u8, &Section<'_>)> = with_room(reuse(lists_of.sub_sections), room);
    sub_sections.extend(subs.iter().map(|&(_, s)| s));
    let by_object = subs;
    let subs = sub_sections;
    let builder = EntryBuilder { is_dcf: model.kind == FileKind::Dcf, secs, compact_template: false };
    // Where the sub-object sections of the previous object ended. Objects usually come in
    // ascending order, so the next object's sub-objects are found by looking on from there (a
    // few steps), and by a binary search only when they are not close.
    let mut next = 0;
    // The objects in file order: sorted once at the end if the file did not list them in
    // ascending order (inserting each into the sorted map would move the later ones every time).
    let mut built: Vec<Object> =
        with_room(std::mem::take(&mut cx.pool.objects), objects.len().max(cx.pool.room / 256 + 8));
    for &(index, sec) in &objects {
        let mut from = next;
        if from > 0 && sub_indices[from - 1] >= index {
            from = sub_indices.partition_point(|&i| i < index);
        } else {
            let near = sub_indices.len().min(from + 8);
            while from < near && sub_indices[from] < index {
                from += 1;
            }
            if from == near && from < sub_indices.len() && sub_indices[from] < index {
                from += sub_indices[from..].partition_point(|&i| i < index);
            }
        }
        let mut to = from;
        while to < sub_indices.len() && sub_indices[to] == index {
            to += 1;
        }
        next = to;
        let (mut names, mut values, mut links) = (None, None, None);
        if !side.is_empty() {
            let at = side.partition_point(|&(i, _, _)| i < index);
            for &(_, which, s) in side[at..].iter().take_while(|&&(i, _, _)| i == index) {
                match which {
                    0 => names = Some(s),
                    1 => values = Some(s),
                    _ => links = Some(s),
                }
            }
        }
        // (Held to the index of all sections in every debug build: the corpus and fixture tests.)
        #[cfg(debug_assertions)]
        for (found, kind) in [(names, Kind::Names(index)), (values, Kind::Values(index)), (links, Kind::Links(index))] {
            debug_assert!(
                found.map(|s| s as *const Section<'_>) == secs.get(kind).map(|s| s as *const Section<'_>),
                "{kind:?}"
            );
        }
        let mut obj = build_object(cx, &builder, index, sec, &subs[from..to], names, values);
        if let Some(l) = links {
            let oname = obj.name.clone();
            let ctx = Crumbs::object(index, &oname);
            for (_, kv) in numbered(cx, l, &OBJECT_LINKS, ctx) {
                let mut q = Vec::new();
                match value::parse_int(kv.value(), &mut q) {
                    Ok(p) if (0..=0xFFFF).contains(&p.value) => obj.object_links.push(Index(p.value as u16)),
                    _ => {
                        let d = cx.emit(
                            codes::E0214,
                            Some(kv.value_span(&cx.src.text)),
                            format!("object link `{}` is not an index (ignored)", kv.value()),
                        );
                        d.context = ctx.to_vec();
                    }
                }
            }
        }
        obj.category = lists.category(index).unwrap_or_else(|| expected_category(index));
        built.push(obj);
    }
    if model.objects.is_empty() {
        // (One object per object section: no index twice.)
        model.objects = ObjectMap::from_unique_values(built);
    } else {
        model.objects.extend(built.into_iter().map(|o| (o.index, o)));
    }
    // Sub-objects and side sections without an object section.
    // Both index lists are sorted: one walk along them finds the sub-objects of no object.
    let mut objects_at = object_indices.iter().peekable();
    for (&i, &(_, sec)) in sub_indices.iter().zip(&subs) {
        while objects_at.next_if(|&&o| o < i).is_some() {}
        if objects_at.peek() != Some(&&i) {
            orphans.push(sec);
        }
    }
    orphans.sort_by_key(|s| s.name_span.start);
    for sec in orphans {
        let index = match sec.kind {
            Kind::Sub(i, _) | Kind::Names(i) | Kind::Values(i) | Kind::Links(i) => i,
            _ => continue,
        };
        let code = if matches!(sec.kind, Kind::Sub(..)) { codes::E0211 } else { codes::E0214 };
        let d =
            cx.emit(code, Some(sec.name_span), format!("[{}] has no object section [{index:04X}]; ignored", sec.name));
        d.hint =
            Some(format!("add the object section [{index:04X}] with ParameterName, ObjectType and SubNumber").into());
    }
    cx.pool.lists = super::pool::ObjectLists {
        objects: reuse(objects),
        subs: reuse(by_object),
        sub_sections: reuse(subs),
        sub_indices,
        object_indices,
    };
}

fn build_object(
    cx: &mut Ctx<'_>,
    builder: &EntryBuilder<'_>,
    index: u16,
    sec: &Section<'_>,
    subs: &[(u8, &Section<'_>)],
    names: Option<&Section<'_>>,
    values: Option<&Section<'_>>,
) -> Object {
    let ctx = Crumbs::object_named_by(index, sec.entries, sec.name);
    let mut keys = Keys::new();
    fill_keys(cx, sec, &OBJ_KEYS, ctx, true, &mut keys);
    let mut name = match keys.get(K_NAME) {
        Some(kv) => Name::from(kv.value()),
        None => {
            let d = cx.emit(codes::E0201, Some(sec.name_span), format!("[{}] lacks ParameterName", sec.name));
            d.hint = Some("add `ParameterName=...`".into());
            d.context = ctx.to_vec();
            Name::new()
        }
    };
    let has_compact = keys.get(K_COMPACT).is_some();
    let looks_structured = !subs.is_empty() || keys.get(K_SUBNUM).is_some() || has_compact;
    let object_type = match keys.get(K_OTYPE) {
        Some(kv) => {
            match uint_key(cx, kv, 0xFF, ctx).ok().and_then(|c| ObjectType::from_code(c as u8)) {
                Some(t) => t,
                None => {
                    let assumed = if looks_structured { ObjectType::Record } else { ObjectType::Var };
                    let d = cx.emit(
                        codes::E0203,
                        Some(kv.value_span(&cx.src.text)),
                        format!("ObjectType `{}` is not an object code; {} assumed", kv.value(), otype(assumed)),
                    );
                    d.hint = Some("object codes are 0x0 NULL, 0x2 DOMAIN, 0x5 DEFTYPE, 0x6 DEFSTRUCT, 0x7 VAR, 0x8 ARRAY, 0x9 RECORD".into());
                    d.context = ctx.to_vec();
                    assumed
                }
            }
        }
        None if looks_structured => {
            let assumed = if has_compact { ObjectType::Array } else { ObjectType::Record };
            let d = cx.emit(
                codes::E0203,
                Some(sec.name_span),
                format!("[{}] lacks ObjectType but has sub-objects; {} assumed", sec.name, otype(assumed)),
            );
            d.hint = Some(format!("add `ObjectType=0x{:X}`", assumed.code()).into());
            d.context = ctx.to_vec();
            assumed
        }
        None => {
            if !cx.skips(codes::E0202) {
                cx.emit(
                    codes::E0202,
                    Some(sec.name_span),
                    super::cat(["[", sec.name, "] lacks ObjectType; VAR assumed"]),
                )
                .context = ctx.to_vec();
            }
            ObjectType::Var
        }
    };
    // The name is copied only for a VAR or DOMAIN, whose entry at sub-index 0 bears it too.
    let single_entry = !object_type.has_subs() && object_type != ObjectType::Null;
    let mut obj = Object {
        index: Index(index),
        name: if single_entry { name.clone() } else { std::mem::take(&mut name) },
        object_type,
        category: crate::model::Category::Optional,
        subs: SubMap::with_capacity(if !object_type.has_subs() {
            1
        } else {
            // CompactSubObj=n adds sub-indices 0..=n (a sub-object section may override one),
            // unless the file is past its bound of implicit elements (E0222): then no room is
            // reserved for them either (7,500 arrays reserving 256 entries each are 200 MB).
            let compact = keys.get(K_COMPACT).and_then(|kv| value::parse_plain_uint(kv.value())).map_or(0, |(n, _)| n);
            let compact = compact.min(0xFF) as usize;
            let implied = if cx.implicit_exceeded || compact > cx.implicit_left { 0 } else { compact };
            subs.len() + 1 + implied
        }),
        compact_sub_obj: None,
        object_links: Vec::new(),
        obj_flags: None,
        extra: Vec::new(),
        at: source_ref(sec),
    };
    if !object_type.has_subs() {
        if object_type != ObjectType::Null {
            let defaults = if object_type == ObjectType::Domain {
                EntryDefaults { data_type: Some(DataType::Domain), access: Some(Access::Rw) }
            } else {
                EntryDefaults::default()
            };
            if let Some(e) = builder.build(cx, sec, &keys, 0, Some(std::mem::take(&mut name)), defaults, ctx) {
                obj.subs.insert(SubIndex(0), e);
            }
        } else {
            keep_entry_keys(cx, &keys, object_type, ctx, &mut obj.extra);
            obj.extra.extend(keys.unknown.iter().map(|kv| owned(kv)));
        }
        if let Some(&(_, first)) = subs.first() {
            let d = cx.emit(
                codes::E0220,
                Some(first.name_span),
                format!(
                    "{} object 0x{index:04X} has no sub-objects, but [{}] defines one (ignored)",
                    otype(object_type),
                    first.name
                ),
            );
            d.hint = Some("make the object an ARRAY (0x8) or RECORD (0x9), or remove the sub-object sections".into());
            d.context = ctx.to_vec();
        }
        for side in [names, values].into_iter().flatten() {
            let d = cx.emit(
                codes::E0214,
                Some(side.name_span),
                format!("[{}] belongs to an object without CompactSubObj (ignored)", side.name),
            );
            d.context = ctx.to_vec();
        }
        return obj;
    }

    // ARRAY, RECORD, DEFSTRUCT.
    obj.obj_flags = keys.get(K_FLAGS).and_then(|kv| match uint_key(cx, kv, u32::MAX, ctx) {
        Ok(v) => Some(v),
        Err(()) => {
            let d = cx.emit(
                codes::E0216,
                Some(kv.value_span(&cx.src.text)),
                format!("ObjFlags `{}` is not a number (kept as text)", kv.value()),
            );
            d.context = ctx.to_vec();
            obj.extra.push(owned(kv));
            None
        }
    });
    let sub_number = keys.get(K_SUBNUM).and_then(|kv| match uint_key(cx, kv, 0x100, ctx) {
        Ok(n) => Some(n),
        Err(()) => {
            let d = cx.emit(
                codes::E0209,
                Some(kv.value_span(&cx.src.text)),
                format!("SubNumber `{}` is not a number 0..=256", kv.value()),
            );
            d.context = ctx.to_vec();
            obj.extra.push(owned(kv));
            None
        }
    });
    let compact = keys.get(K_COMPACT).and_then(|kv| match uint_key(cx, kv, 0xFF, ctx) {
        Ok(n) => {
            if n == 0xFF {
                let d = cx.emit(
                    codes::E0213,
                    Some(kv.value_span(&cx.src.text)),
                    "CompactSubObj=255 defines sub-index 0xFF",
                );
                d.hint =
                    Some("CiA 301 reserves sub-index 0xFF for the structure of the object; 254 is the most".into());
                d.context = ctx.to_vec();
            }
            Some(n as u8)
        }
        Err(()) => {
            let d = cx.emit(
                codes::E0213,
                Some(kv.value_span(&cx.src.text)),
                format!("CompactSubObj `{}` is not a number 0..=255", kv.value()),
            );
            d.context = ctx.to_vec();
            obj.extra.push(owned(kv));
            None
        }
    });
    // False when the implicit elements were not added (E0222): the checks of sub-index 0
    // against the elements would only repeat that.
    let mut expanded = true;
    if let Some(n) = compact {
        if object_type != ObjectType::Array
            && let Some(kv) = keys.get(K_COMPACT)
        {
            let d = cx.emit(
                codes::E0213,
                Some(kv.key_span(&cx.src.text)),
                format!("CompactSubObj on object type {} (CiA 306 allows it on ARRAY only)", otype(object_type)),
            );
            d.context = ctx.to_vec();
        }
        if let (Some(_), Some(kv)) = (sub_number, keys.get(K_SUBNUM)) {
            let d =
                cx.emit(codes::E0213, Some(kv.key_span(&cx.src.text)), "both SubNumber and CompactSubObj are given");
            d.hint = Some("use CompactSubObj alone for the compact form, or SubNumber with sub-object sections".into());
            d.context = ctx.to_vec();
        }
        obj.compact_sub_obj = Some(n);
        expanded = expand_compact(cx, builder, &mut obj, sec, &keys, n, names, values, ctx);
    } else {
        keep_entry_keys(cx, &keys, object_type, ctx, &mut obj.extra);
        for side in [names, values].into_iter().flatten() {
            let d = cx.emit(
                codes::E0214,
                Some(side.name_span),
                format!("[{}] belongs to an object without CompactSubObj (ignored)", side.name),
            );
            d.context = ctx.to_vec();
        }
    }
    obj.extra.extend(keys.unknown.iter().map(|kv| owned(kv)));
    let mut skeys = Keys::new();
    for &(sub, ssec) in subs {
        let sctx = ctx.sub_named_by(sub, ssec.entries);
        skeys.clear();
        fill_keys(cx, ssec, &OBJ_KEYS, sctx, true, &mut skeys);
        if let Some(kv) = skeys.get(K_OTYPE)
            && uint_key(cx, kv, 0xFF, sctx) != Ok(0x7)
        {
            let d = cx.emit(
                codes::E0218,
                Some(kv.value_span(&cx.src.text)),
                format!("sub-object ObjectType `{}` is not 0x7 (VAR)", kv.value()),
            );
            d.context = sctx.to_vec();
        }
        if compact.is_some() && obj.subs.contains_key(&SubIndex(sub)) {
            let d = cx.emit(
                codes::E0213,
                Some(ssec.name_span),
                format!("[{}] overrides a sub-object that CompactSubObj defines", ssec.name),
            );
            d.context = sctx.to_vec();
        }
        if let Some(e) = builder.build(cx, ssec, &skeys, sub, None, EntryDefaults::default(), sctx) {
            obj.subs.insert(SubIndex(sub), e);
        }
    }
    if expanded {
        check_structure(cx, &obj, sec, &keys, sub_number, compact, subs, ctx);
        let highest_section = subs.iter().map(|&(sub, _)| sub).max();
        super::validate::sub_index_zero(builder.secs, &obj, highest_section, cx);
    }
    obj
}

#[allow(clippy::too_many_arguments)]
fn expand_compact(
    cx: &mut Ctx<'_>,
    builder: &EntryBuilder<'_>,
    obj: &mut Object,
    sec: &Section<'_>,
    keys: &ObjKeys<'_>,
    n: u8,
    names: Option<&Section<'_>>,
    values: Option<&Section<'_>>,
    ctx: Crumbs<'_>,
) -> bool {
    // Sub-index 0 holds the number of entries (named as lely-core and CiA 306 examples do).
    let sub0 = (
        SubIndex(0),
        Entry {
            sub: SubIndex(0),
            name: Name::from("NrOfObjects"),
            data_type: DataType::Unsigned8,
            access: Access::Ro,
            pdo_mapping: false,
            default: Some(Value::int(n as i128)),
            extras: None,
            at: obj.at,
        },
    );
    let template_builder = EntryBuilder { compact_template: true, ..*builder };
    let Some(template) =
        template_builder.build(cx, sec, keys, 1, Some(obj.name.clone()), EntryDefaults::default(), ctx)
    else {
        obj.subs.insert(sub0.0, sub0.1);
        return true;
    };
    obj.subs.insert(sub0.0, sub0.1);
    if cx.implicit_left < n as usize || cx.implicit_exceeded {
        if !cx.implicit_exceeded {
            cx.implicit_exceeded = true;
            let declared = super::implicit_budget(cx.src.text.len()) - cx.implicit_left + n as usize;
            let span = keys.get(K_COMPACT).map(|kv| kv.value_span(&cx.src.text));
            let d = cx.emit(
                codes::E0222,
                span,
                format!(
                    "CompactSubObj={n} brings the file's implicit elements to {declared}, more than a file of its size \
                     may declare; this and later compact arrays keep only sub-index 0"
                ),
            );
            d.hint = Some(
                "a resource limit (65,536 implicit elements, and one per 64 bytes of file beyond that): write the \
                 elements out as sub-object sections, or split the file"
                    .into(),
            );
            d.context = ctx.to_vec();
        }
        return false;
    }
    cx.implicit_left -= n as usize;
    // Each element is the template with its own name and without the template's extra keys
    // (those stay with the object): copy the other fields, and clone no name or list only to
    // replace it. Most templates have no extras at all, and the elements then share nothing.
    let t = &template;
    let extras = t.extras.as_ref().map(|x| EntryExtras { extra: Vec::new(), ..EntryExtras::clone(x) });
    let extras = extras.filter(|x| !x.is_empty()).map(Box::new);
    let base = &obj.name;
    obj.subs.extend_with(1..=n, |s| {
        let name = base.with_number(s);
        Entry {
            sub: SubIndex(s),
            name,
            data_type: t.data_type,
            access: t.access,
            pdo_mapping: t.pdo_mapping,
            default: t.default.clone(),
            extras: extras.clone(),
            at: t.at,
        }
    });
    if let Some(ns) = names {
        for (k, kv) in numbered(cx, ns, &NR_OF_ENTRIES, ctx) {
            match obj.subs.get_mut(&SubIndex(k.min(256) as u8)).filter(|_| (1..=n as u32).contains(&k)) {
                Some(e) => e.name = Name::from(kv.value()),
                None => {
                    let d = cx.emit(
                        codes::E0214,
                        Some(kv.key_span(&cx.src.text)),
                        format!("[{}] names sub-index {k}, but CompactSubObj={n}", ns.name),
                    );
                    d.context = ctx.to_vec();
                }
            }
        }
    }
    if let Some(vs) = values {
        for (k, kv) in numbered(cx, vs, &NR_OF_ENTRIES, ctx) {
            let Some(e) = obj.subs.get_mut(&SubIndex(k.min(256) as u8)).filter(|_| (1..=n as u32).contains(&k)) else {
                let d = cx.emit(
                    codes::E0214,
                    Some(kv.key_span(&cx.src.text)),
                    format!("[{}] sets sub-index {k}, but CompactSubObj={n}", vs.name),
                );
                d.context = ctx.to_vec();
                continue;
            };
            let ename = e.name.clone();
            let sctx = ctx.sub(k as u8, &ename);
            let ty = e.data_type;
            // [xxxxValue] holds the configured value of each sub-object (lely-core's reading).
            let v = value_key(cx, kv, ty, sctx);
            if let Some(e) = obj.subs.get_mut(&SubIndex(k as u8)) {
                match v {
                    Ok(v) => e.set_parameter_value(v),
                    Err(()) => e.extras_mut().extra.push(("ParameterValue".to_owned(), kv.value().to_owned())),
                }
            }
        }
    }
    true
}

#[allow(clippy::too_many_arguments)]
fn check_structure(
    cx: &mut Ctx<'_>,
    obj: &Object,
    sec: &Section<'_>,
    keys: &ObjKeys<'_>,
    sub_number: Option<u32>,
    compact: Option<u8>,
    subs: &[(u8, &Section<'_>)],
    ctx: Crumbs<'_>,
) {
    if compact.is_none() {
        match (sub_number, keys.get(K_SUBNUM)) {
            (Some(n), Some(kv)) if n as usize != subs.len() => {
                let d = cx.emit(
                    codes::E0209,
                    Some(kv.value_span(&cx.src.text)),
                    format!("SubNumber={n} but the file has {} sub-object sections", subs.len()),
                );
                d.hint = Some(format!("set SubNumber={}", subs.len()).into());
                d.context = ctx.to_vec();
            }
            (None, None) => {
                let d = cx.emit(codes::E0209, Some(sec.name_span), format!("[{}] lacks SubNumber", sec.name));
                d.hint = Some(format!("add `SubNumber={}`", subs.len()).into());
                d.context = ctx.to_vec();
            }
            _ => {}
        }
    }
    match obj.subs.get(&SubIndex(0)) {
        None => {
            let d = cx.emit(
                codes::E0212,
                Some(sec.name_span),
                format!(
                    "{} object 0x{:04X} has no sub-index 0 (the number of entries)",
                    otype(obj.object_type),
                    obj.index.0
                ),
            );
            d.hint = Some(
                format!("add [{:04X}sub0] with DataType=0x0005 (UNSIGNED8) and AccessType=ro", obj.index.0).into(),
            );
            d.context = ctx.to_vec();
        }
        Some(e) if e.data_type != DataType::Unsigned8 => {
            let span = subs.iter().find(|(s, _)| *s == 0).map(|(_, s)| s.name_span);
            let c = ctx.sub(0, &e.name).to_vec();
            let d = cx.emit(codes::E0210, span, format!("sub-index 0 is {} but must be UNSIGNED8", e.data_type.name()));
            d.hint = Some("write DataType=0x0005".into());
            d.context = c;
        }
        Some(_) => {}
    }
    // The elements CompactSubObj makes share one type: only sub-object sections (other than
    // sub-index 0's) can bring another, and without them the elements need no comparing.
    let one_type = compact.is_some() && subs.iter().all(|&(s, _)| s == 0);
    if obj.object_type == ObjectType::Array && !one_type {
        let mut types = obj.subs.values().filter(|e| e.sub.0 != 0).map(|e| (e.sub.0, e.data_type));
        if let Some((first_sub, first)) = types.next()
            && let Some((s, other)) = types.find(|&(_, t)| t != first)
        {
            // The element's own section; an element CompactSubObj made has none: then the
            // section of the first element (which overrides the compact type), else the
            // object's CompactSubObj key, else its header. Always a place in the file.
            let section_of = |sub: u8| subs.iter().find(|(x, _)| *x == sub).map(|(_, sec)| sec.name_span);
            let span = section_of(s)
                .or_else(|| section_of(first_sub))
                .or_else(|| keys.get(K_COMPACT).map(|kv| kv.key_span(&cx.src.text)))
                .or(Some(sec.name_span));
            let d = cx.emit(
                codes::E0219,
                span,
                format!("ARRAY element {s} is {} while the first element is {}", other.name(), first.name()),
            );
            d.hint = Some("an ARRAY holds elements of one type; use a RECORD (ObjectType=0x9) for mixed types".into());
            d.context = ctx.to_vec();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An empty value reads as the general rules read it, for every type code, with no
    /// diagnostic either way.
    #[test]
    fn empty_values_are_what_the_general_rules_read() {
        let src = crate::source::SourceFile::decode("t.eds", b"DefaultValue=\n");
        let text = src.text.clone();
        let kv = Kv::new(&text, crate::source::Span::new(0, 12), crate::source::Span::new(13, 13));
        assert_eq!(kv.value(), "");
        let mut cx = Ctx::new(&src, crate::Strictness::default());
        for code in 0..=u16::MAX {
            let ty = DataType::from_code(code);
            let fast = value_key(&mut cx, &kv, ty, Crumbs::default());
            let general = value_key_other(&mut cx, &kv, ty, Crumbs::default());
            assert_eq!(fast, general, "{ty:?}");
        }
        assert!(cx.diags.is_empty(), "{:?}", cx.diags.first().map(|d| &d.message));
    }

    /// Where the shortcut for plain integers gives a value, it is the one the general rules
    /// give, with no remark and within range; it gives one for the plain forms in range.
    #[test]
    fn plain_int_values_are_what_the_general_rules_read() {
        let mut types: Vec<DataType> = DataType::BASIC.to_vec();
        types.push(DataType::Other(0x40));
        let mut texts: Vec<String> = [
            "0",
            "1",
            "2",
            "00",
            "01",
            "08",
            "10",
            "127",
            "128",
            "255",
            "256",
            "65535",
            "65536",
            "0x",
            "0x0",
            "0X1a",
            "0x7F",
            "0x80",
            "0xFF",
            "0x100",
            "0x7FFF",
            "0x8000",
            "0xFFFF",
            "0x10000",
            "0x7FFFFFFF",
            "0x80000000",
            "0xFFFFFFFF",
            "0x100000000",
            "0x7FFFFFFFFFFFFFFF",
            "0x8000000000000000",
            "0xFFFFFFFFFFFFFFFF",
            "0x10000000000000000",
            "9223372036854775807",
            "9223372036854775808",
            "18446744073709551615",
            "18446744073709551616",
            " 1",
            "1 ",
            "-1",
            "+1",
            "1.5",
            "1e3",
            "$NODEID+1",
            "true",
            "",
            "1U",
            "0b1",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        for bits in [7, 8, 15, 16, 23, 24, 31, 32, 39, 40, 47, 48, 55, 56, 63] {
            for v in [(1u64 << bits) - 1, 1u64 << bits] {
                texts.push(v.to_string());
                texts.push(format!("0x{v:X}"));
            }
        }
        let mut fast = 0;
        for ty in types {
            for text in &texts {
                let Some(v) = plain_int_value(text, ty) else { continue };
                fast += 1;
                let parsed = value::parse_value(text, ty).expect("readable");
                assert_eq!(parsed.value.as_ref(), Some(&v), "{text:?} as {ty:?}");
                assert!(parsed.quirks.is_empty(), "{text:?} as {ty:?}");
                assert_eq!(value::check_range(&v, ty), Ok(()), "{text:?} as {ty:?}");
            }
        }
        assert!(fast > 200, "{fast}");
        assert_eq!(plain_int_value("0x80", DataType::Integer8), None);
        assert_eq!(plain_int_value("256", DataType::Unsigned8), None);
        assert_eq!(plain_int_value("2", DataType::Boolean), None);
    }
}
