//! The naming policy as properties over random vendor-like names (`ident`): every name is a
//! valid Rust identifier that starts with a letter and never with a number in disguise (`x1…`,
//! `X2…`), a clean name maps to itself (so names are stable under regeneration), the field's
//! mixed-case words stay whole, and the accessors of a model built from such names are unique
//! in their scope (getters and `set_` setters together, ignoring case).

mod common;

use std::collections::BTreeSet;

use eds::model::{Access, DataType, ObjectType};
use od_codegen::ident;
use proptest::prelude::*;

/// The ways vendors write a leading number (`{n}` is the number).
const LEADS: &[&str] = &[
    "{n}.", "{n})", "{n}-", "{n} -", "{n}:", "#{n}", "{n}st", "{n}nd", "{n}rd", "{n}th", "{n}rst", "{n}er", "{n}eme",
    "{n}ème", "{n}V", "{n}-Bit", "{n}-axis", "{n}mA", "{n}", "{n}-{n}", "({n})", "{n}º",
];

/// Words of vendor names: plain, camel-case, acronyms with plurals, the field's mixed-case
/// words, units, non-ASCII, keywords and numbers.
const WORDS: &[&str] = &[
    "Receive",
    "PDO",
    "parameter",
    "COB-ID",
    "used",
    "by",
    "supply",
    "DC",
    "Analog",
    "input",
    "Output",
    "CANopen",
    "EtherCAT",
    "CiA402",
    "BiSS",
    "IOs",
    "PDOs",
    "IDs",
    "mA",
    "kHz",
    "homeOffset",
    "TPDOMapping",
    "RxPDO1",
    "Übergröße",
    "°C",
    "type",
    "self",
    "Self",
    "new",
    "2nd",
    "1",
    "10",
    "[mm/s]",
    "(rpm)",
    "won't",
    "X",
    "motor",
    "Nm",
    "µs",
];

const SEPARATORS: &[&str] = &[" ", "  ", "-", "_", "/", " / ", ", ", "."];

prop_compose! {
    fn vendor_name()(
        lead in proptest::option::of((0..LEADS.len(), 0u32..130)),
        words in proptest::collection::vec((0..WORDS.len(), 0..SEPARATORS.len()), 0..6),
    ) -> String {
        let mut s = String::new();
        if let Some((l, n)) = lead {
            s.push_str(&LEADS[l].replace("{n}", &n.to_string()));
            s.push(' ');
        }
        for (w, sep) in words {
            s.push_str(WORDS[w]);
            s.push_str(SEPARATORS[sep]);
        }
        s
    }
}

fn is_ident(s: &str) -> bool {
    syn::parse_str::<syn::Ident>(s).is_ok()
}

/// Whether `s` starts with a number or a number in disguise (`x2…`, `X2…`).
fn starts_with_number(s: &str) -> bool {
    let b = s.as_bytes();
    b.first().is_some_and(u8::is_ascii_digit)
        || (matches!(b.first(), Some(b'x' | b'X')) && b.get(1).is_some_and(u8::is_ascii_digit))
}

/// Whether the name's own first word is an `x` (`X1 axis`, `X 0`): then an `x` and a digit is a
/// word of the name, not a prefix the generator added.
fn first_word_is_x(name: &str) -> bool {
    ident::words(name).first().is_some_and(|w| w.starts_with('x'))
}

fn check_forms(name: &str) -> Result<(), TestCaseError> {
    let forms = [ident::snake(name), ident::screaming(name), ident::camel(name)];
    let words = ident::words(name);
    prop_assert!(!words.first().is_some_and(|w| w.starts_with(|c: char| c.is_ascii_digit())), "{name:?}: {words:?}");
    let have = forms.iter().filter(|f| f.is_some()).count();
    prop_assert!(have == 0 || have == 3, "{name:?}: {forms:?}");
    for f in forms.into_iter().flatten() {
        prop_assert!(is_ident(&f), "{name:?} → {f:?} is not an identifier");
        prop_assert!(f.is_ascii() && !f.contains("__"), "{name:?} → {f:?}");
        prop_assert!(!starts_with_number(&f) || first_word_is_x(name), "{name:?} → {f:?}");
    }
    if let Some(s) = ident::snake(name) {
        // A clean name maps to itself: regenerating from a generated name changes nothing.
        prop_assert_eq!(ident::snake(&s), Some(s.clone()), "{:?}", name);
        prop_assert_eq!(ident::snake(name), Some(s.clone()), "not deterministic: {:?}", name);
        // The field's mixed-case words stay whole.
        for w in ident::FIELD_WORDS {
            if name.split(|c: char| !c.is_ascii_alphanumeric()).any(|t| t == *w) {
                let whole = w.to_ascii_lowercase();
                prop_assert!(s.split('_').any(|p| p == whole), "{name:?} → {s:?} splits {w}");
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn vendor_names_give_identifiers_that_start_with_a_word(name in vendor_name()) {
        check_forms(&name)?;
    }

    #[test]
    fn any_text_gives_an_identifier_or_none(name in "\\PC{0,24}") {
        check_forms(&name)?;
    }

    /// A model of objects (with records) named like vendors name them: every accessor is an
    /// identifier that starts with a word, unique with its setter in the dictionary's scope,
    /// and the same on a second run.
    #[test]
    fn accessors_of_vendor_names_are_unique_and_stable(
        objects in proptest::collection::vec((vendor_name(), proptest::collection::vec(vendor_name(), 0..4)), 1..8),
    ) {
        let mut objs = Vec::new();
        for (i, (name, subs)) in objects.iter().enumerate() {
            let index = 0x2000 + i as u16;
            if subs.is_empty() {
                objs.push(common::var(index, name, DataType::Unsigned16, Access::Rw, None, false));
            } else {
                let mut entries = vec![common::entry(0, "Number of entries", DataType::Unsigned8, Access::Ro, None, false)];
                for (s, sub) in subs.iter().enumerate() {
                    entries.push(common::entry(s as u8 + 1, sub, DataType::Unsigned16, Access::Rw, None, false));
                }
                objs.push(common::object(index, name, ObjectType::Record, entries));
            }
        }
        let model = common::model(objs);
        let names = od_codegen::accessor_names(&model);
        prop_assert_eq!(&names, &od_codegen::accessor_names(&model));
        let mut seen = BTreeSet::new();
        for (index, sub, n) in &names {
            prop_assert!(is_ident(n), "{n:?}");
            prop_assert!(!starts_with_number(n), "{index:04x}/{sub}: {n:?}");
            prop_assert!(seen.insert(n.to_ascii_lowercase()), "{n:?} twice");
        }
        for (_, _, n) in &names {
            prop_assert!(!seen.contains(&format!("set_{n}")), "set_{n} is also a getter");
        }
    }
}
