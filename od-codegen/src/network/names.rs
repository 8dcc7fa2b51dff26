//! Names of dictionary entries, as the generated code spells them.
//!
//! A network description names objects the way the generated Rust does: each entry by its
//! accessor in the code `od-codegen` generates for the device (`Position actual value` →
//! `position_actual_value`; `Identity object` / `Vendor-ID` → `identity_object_vendor_id`),
//! taken from [`crate::accessor_names`] so the two never disagree, and an ARRAY or RECORD
//! by the name its entries' accessors start with ([`crate::object_names`]). Objects that
//! hold no value (DEFTYPE, DEFSTRUCT, NULL) and entries of complex data types are not in the
//! generated code and have no name here either; they can still be named by index
//! (`0x2001sub1`).
//!
//! A test in `odgen/tests/network.rs` checks every name of the three devices against the code
//! `od-codegen` generates for them.

use std::collections::BTreeMap;

use eds::model::Model;

/// What a name stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Named {
    /// One entry: `(index, sub-index)`.
    Entry(u16, u8),
    /// An ARRAY or RECORD object (not a single value).
    Object(u16),
}

/// Every entry name of one device.
#[derive(Clone, Debug, Default)]
pub struct NameIndex {
    entries: BTreeMap<String, (u16, u8)>,
    objects: BTreeMap<String, u16>,
    by_entry: BTreeMap<(u16, u8), String>,
}

impl NameIndex {
    /// Names the entries of `model` as the generated code does.
    pub fn new(model: &Model) -> Self {
        let mut out = NameIndex::default();
        for (index, name) in crate::object_names(model) {
            if model.objects.get(&eds::model::Index(index)).is_some_and(|o| o.object_type.has_subs()) {
                out.objects.entry(name).or_insert(index);
            }
        }
        for (index, sub, name) in crate::accessor_names(model) {
            out.by_entry.insert((index, sub), name.clone());
            out.entries.insert(name, (index, sub));
        }
        out
    }

    /// What `name` stands for: an entry, or (when no entry has that name) an ARRAY or RECORD.
    pub fn get(&self, name: &str) -> Option<Named> {
        if let Some(&(i, s)) = self.entries.get(name) {
            return Some(Named::Entry(i, s));
        }
        self.objects.get(name).map(|&i| Named::Object(i))
    }

    /// The name of entry `(index, sub)`, if it has one.
    pub fn name_of(&self, index: u16, sub: u8) -> Option<&str> {
        self.by_entry.get(&(index, sub)).map(String::as_str)
    }

    /// Every entry name with its entry, sorted by name.
    pub fn iter(&self) -> impl Iterator<Item = (&str, (u16, u8))> {
        self.entries.iter().map(|(k, v)| (k.as_str(), *v))
    }

    /// The entry names of ARRAY/RECORD object `index`, in sub-index order.
    pub fn entries_of(&self, index: u16) -> Vec<&str> {
        self.by_entry.range((index, 0)..=(index, u8::MAX)).map(|(_, n)| n.as_str()).collect()
    }

    /// Up to three entry names close to `wanted`, closest first (for "did you mean").
    ///
    /// Close means a small edit distance (at most a third of the name's length, at least 2),
    /// or, failing that, names containing every word of `wanted`.
    pub fn suggest(&self, wanted: &str) -> Vec<&str> {
        suggest(wanted, self.entries.keys().map(String::as_str))
    }
}

/// Up to three of `candidates` close to `wanted`, closest first.
pub fn suggest<'a>(wanted: &str, candidates: impl Iterator<Item = &'a str> + Clone) -> Vec<&'a str> {
    let limit = (wanted.chars().count() / 3).max(2);
    let mut close: Vec<(usize, &str)> = candidates
        .clone()
        .filter_map(|c| {
            let d = distance(wanted, c);
            (d <= limit).then_some((d, c))
        })
        .collect();
    close.sort();
    if close.is_empty() {
        let words: Vec<&str> = wanted.split('_').filter(|w| w.len() > 1).collect();
        if !words.is_empty() {
            close = candidates
                .filter(|c| words.iter().all(|w| c.split('_').any(|cw| cw.starts_with(w))))
                .map(|c| (c.len(), c))
                .collect();
            close.sort();
        }
    }
    close.into_iter().take(3).map(|(_, c)| c).collect()
}

/// Optimal string alignment distance (Levenshtein plus adjacent transpositions).
pub fn distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let (n, m) = (a.len(), b.len());
    let mut d = vec![vec![0usize; m + 1]; n + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=n {
        for j in 1..=m {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut v = (d[i - 1][j] + 1).min(d[i][j - 1] + 1).min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                v = v.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = v;
        }
    }
    d[n][m]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        assert_eq!(distance("statusword", "statusword"), 0);
        assert_eq!(distance("statusward", "statusword"), 1);
        assert_eq!(distance("stauts", "status"), 1);
        assert_eq!(distance("", "abc"), 3);
    }

    #[test]
    fn suggestions() {
        let names = ["statusword", "controlword", "position_actual_value", "target_position"];
        assert_eq!(suggest("statusward", names.iter().copied()), vec!["statusword"]);
        assert_eq!(suggest("actual_pos", names.iter().copied()), vec!["position_actual_value"]);
        assert!(suggest("zzzzzzzz", names.iter().copied()).is_empty());
    }
}
