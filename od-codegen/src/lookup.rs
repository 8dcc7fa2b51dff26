//! The lookup tables of a generated dictionary: `(index, sub)` → position in `ENTRIES`.
//!
//! The generator computes the tables the runtime's `Lookup` walks (see
//! `od_runtime::__private_v1::Lookup`): a two-level page table from an index to its object's
//! number, then the sub-index within the object's run of entries. Building them here, once,
//! keeps the lookup free of searches: a table read per step and, for the rare object whose
//! sub-indices have gaps, a binary search of that object's few entries.

use proc_macro2::{Literal, TokenStream};
use quote::quote;

use crate::lit;
use crate::support::rt;

/// The most objects the tables can number (slots hold `object + 1` in a `u16`). 65535 objects
/// of at most 256 entries also keep every first entry below 2^24, as `runs` needs.
pub(crate) const MAX_OBJECTS: usize = u16::MAX as usize;

/// The tables for entries with keys `keys`, sorted by `(index, sub)` without duplicates.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Tables {
    /// `(high byte, offset of its page in slots)` for each high byte present; all others map to
    /// page 0, a page of zeros (present unless all 256 high bytes are used).
    pub pages: Vec<(u8, u16)>,
    /// 256 slots per page: object number + 1, or 0.
    pub slots: Vec<u16>,
    /// Per object: `first << 8 | (count - 1)`.
    pub runs: Vec<u32>,
    /// Sub-index of every entry.
    pub subs: Vec<u8>,
}

/// Builds the tables, or `None` for more than [`MAX_OBJECTS`] objects. `keys` must be sorted by
/// `(index, sub)` and free of duplicates (the planner guarantees both).
pub(crate) fn build(keys: &[(u16, u8)]) -> Option<Tables> {
    let mut objects: Vec<(u16, usize, usize)> = Vec::new(); // (index, first, count)
    for (pos, &(index, _)) in keys.iter().enumerate() {
        match objects.last_mut() {
            Some(o) if o.0 == index => o.2 += 1,
            _ => objects.push((index, pos, 1)),
        }
    }
    if objects.len() > MAX_OBJECTS {
        return None;
    }
    let mut highs: Vec<u8> = objects.iter().map(|o| (o.0 >> 8) as u8).collect();
    highs.dedup();
    let zero = usize::from(highs.len() < 256);
    let mut t = Tables {
        pages: highs.iter().enumerate().map(|(k, h)| (*h, ((k + zero) * 256) as u16)).collect(),
        slots: vec![0; (highs.len() + zero) * 256],
        runs: Vec::with_capacity(objects.len()),
        subs: keys.iter().map(|k| k.1).collect(),
    };
    for (n, &(index, first, count)) in objects.iter().enumerate() {
        let high = (index >> 8) as u8;
        let offset = t.pages.iter().find(|p| p.0 == high).map(|p| usize::from(p.1))?;
        *t.slots.get_mut(offset + usize::from(index & 0xFF))? = u16::try_from(n + 1).ok()?;
        let first = u32::try_from(first).ok().filter(|f| *f < 1 << 24)?;
        let last = u32::try_from(count - 1).ok().filter(|l| *l < 256)?;
        t.runs.push(first << 8 | last);
    }
    Some(t)
}

/// `OBJECTS` and `static LOOKUP: ::od_runtime::__private_v1::Lookup = …;`, or `None` for more
/// than [`MAX_OBJECTS`] objects.
///
/// The generated code lists the objects' indices, each object's run of entries and every
/// entry's sub-index; the page table itself is computed from the index list at compile time by
/// the runtime's `const fn`s (the same layout [`build`] describes, which the tests check).
pub(crate) fn tokens(keys: &[(u16, u8)]) -> Option<TokenStream> {
    let t = build(keys)?;
    let rt = rt();
    let mut objects: Vec<u16> = keys.iter().map(|k| k.0).collect();
    objects.dedup();
    let n_objects = Literal::usize_unsuffixed(objects.len());
    let n_slots = Literal::usize_unsuffixed(t.slots.len());
    let objects = objects.iter().map(|i| lit::hex(u64::from(*i), 4));
    let runs = t.runs.iter().map(|r| lit::hex(u64::from(*r), 8));
    let subs = t.subs.iter().map(|s| Literal::u8_unsuffixed(*s));
    Some(quote! {
        /// The index of every object, sorted (the lookup's page table is computed from it).
        static OBJECTS: [u16; #n_objects] = [#(#objects),*];

        /// Finds `(index, sub)` in [`ENTRIES`] in a constant number of steps: a page table from
        /// the index to its object, then the sub-index in the object's run of entries (`runs`:
        /// `0xFFFFFFLL`, the object's first entry `FFFFFF` and its last position in the run `LL`;
        /// `subs`: every entry's sub-index).
        static LOOKUP: #rt::Lookup = #rt::Lookup {
            pages: #rt::pages(&OBJECTS),
            slots: &#rt::slots::<#n_slots>(&OBJECTS),
            runs: &[#(#runs),*],
            subs: &[#(#subs),*],
        };
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use od_runtime::__private_v1::{Lookup, position};
    use od_runtime::od::AbortCode;
    use proptest::prelude::*;

    fn leak<T>(v: Vec<T>) -> &'static [T] {
        Box::leak(v.into_boxed_slice())
    }

    /// The lookup as the generated code builds it: the runtime's `const fn`s compute the page
    /// table from the object list, and must agree with [`build`].
    fn lookup(keys: &[(u16, u8)]) -> Lookup {
        let t = build(keys).unwrap();
        let mut objects: Vec<u16> = keys.iter().map(|k| k.0).collect();
        objects.dedup();
        let mut pages = [0u16; 256];
        for (h, g) in &t.pages {
            pages[usize::from(*h)] = *g;
        }
        assert_eq!(od_runtime::__private_v1::pages(&objects), pages);
        // The largest page count there is; the generator sizes the array exactly.
        let slots = od_runtime::__private_v1::slots::<{ 256 * 256 }>(&objects);
        assert_eq!(&slots[..t.slots.len()], &t.slots[..]);
        assert!(slots[t.slots.len()..].iter().all(|s| *s == 0));
        Lookup { pages, slots: leak(t.slots), runs: leak(t.runs), subs: leak(t.subs) }
    }

    /// What a binary search over the sorted keys says.
    fn expected(keys: &[(u16, u8)], index: u16, sub: u8) -> Result<usize, AbortCode> {
        keys.binary_search(&(index, sub))
            .map_err(|_| if keys.iter().any(|k| k.0 == index) { AbortCode::NO_SUB_INDEX } else { AbortCode::NO_OBJECT })
    }

    fn key_set() -> impl Strategy<Value = Vec<(u16, u8)>> {
        let index =
            prop_oneof![any::<u16>(), 0x1000u16..0x1020, 0x6000u16..0x6100, (0u16..4).prop_map(|i| i * 64 + 63)];
        let sub = prop_oneof![0u8..4, any::<u8>()];
        prop::collection::btree_set((index, sub), 0..300).prop_map(|s| s.into_iter().collect())
    }

    proptest! {
        #[test]
        fn finds_what_a_binary_search_finds(keys in key_set(), probes in prop::collection::vec((any::<u16>(), any::<u8>()), 64)) {
            let l = lookup(&keys);
            for (pos, &(index, sub)) in keys.iter().enumerate() {
                prop_assert_eq!(position(&l, index, sub), Ok(pos));
                prop_assert_eq!(position(&l, index, sub.wrapping_add(1)), expected(&keys, index, sub.wrapping_add(1)));
                prop_assert_eq!(position(&l, index ^ 1, sub), expected(&keys, index ^ 1, sub));
            }
            for (index, sub) in probes {
                prop_assert_eq!(position(&l, index, sub), expected(&keys, index, sub));
            }
        }
    }

    #[test]
    fn every_index_of_a_full_page_and_the_ends_of_the_range() {
        let mut keys: Vec<(u16, u8)> = (0x2000u16..0x2100).map(|i| (i, 0)).collect();
        keys.insert(0, (0, 0));
        keys.extend((0..=255).map(|s| (0x3000, s)));
        keys.extend([(0xFFFF, 0), (0xFFFF, 3), (0xFFFF, 255)]);
        let l = lookup(&keys);
        for (pos, &(index, sub)) in keys.iter().enumerate() {
            assert_eq!(position(&l, index, sub), Ok(pos));
        }
        assert_eq!(position(&l, 0xFFFF, 4), Err(AbortCode::NO_SUB_INDEX));
        assert_eq!(position(&l, 0x2100, 0), Err(AbortCode::NO_OBJECT));
        assert_eq!(position(&l, 0x20FF, 1), Err(AbortCode::NO_SUB_INDEX));
        let empty = lookup(&[]);
        assert_eq!(position(&empty, 0x1000, 0), Err(AbortCode::NO_OBJECT));
    }

    #[test]
    fn at_most_65535_objects() {
        let all: Vec<(u16, u8)> = (0..=u16::MAX).map(|i| (i, 0)).collect();
        assert_eq!(build(&all), None);
        let l = lookup(&all[1..]);
        assert_eq!(position(&l, 0xFFFF, 0), Ok(MAX_OBJECTS - 1));
        assert_eq!(position(&l, 0, 0), Err(AbortCode::NO_OBJECT));
    }
}
