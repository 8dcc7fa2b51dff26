//! The lookup tables of a generated dictionary: `(index, sub)` → position in `ROWS` (and `ENTRIES`).
//!
//! The generator computes the tables the runtime's `Lookup` walks (see
//! `od_runtime::__private_v3::Lookup`): a page per high byte of the index, a 256-bit set per
//! page with the rank of each 64-bit word, then the sub-index within the object's run of
//! entries. Building them here, once, keeps the lookup free of searches: a few table reads
//! and a bit count, and for the rare object whose sub-indices have gaps, a binary search of
//! that object's few entries. At about 40 bytes per page of 256 indices the tables cost a
//! firmware a byte or two per entry.

use proc_macro2::{Literal, TokenStream};
use quote::quote;

use crate::lit;
use crate::support::rt;

/// The most entries (and so objects) the tables can number (ranks are `u16` positions).
pub(crate) const MAX_OBJECTS: usize = u16::MAX as usize;

/// The most pages (distinct high bytes of the indices; page numbers are a `u8` plus one).
pub(crate) const MAX_PAGES: usize = 255;

/// The tables for entries with keys `keys`, sorted by `(index, sub)` without duplicates.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Tables {
    /// Per high byte: page number + 1, or 0.
    pub pages: Vec<u8>,
    /// Per page: the low bytes that have an object.
    pub bits: Vec<[u64; 4]>,
    /// Per page and word: the first entry at or after the word's first index.
    pub ranks: Vec<[u16; 4]>,
    /// Per page and word: the number of the first object at or after the word's first index.
    pub objects: Vec<[u16; 4]>,
    /// Per object: entries of the objects before it in its word beyond one each, at most 255.
    pub extra: Vec<u8>,
}

/// The tables, or `None` past [`MAX_OBJECTS`] objects or [`MAX_PAGES`] pages.
pub(crate) fn build(keys: &[(u16, u8)]) -> Option<Tables> {
    let mut objects: Vec<(u16, usize, usize)> = Vec::new(); // (index, first, count)
    for (pos, &(index, _)) in keys.iter().enumerate() {
        match objects.last_mut() {
            Some(o) if o.0 == index => o.2 += 1,
            _ => objects.push((index, pos, 1)),
        }
    }
    if objects.len() > MAX_OBJECTS || keys.len() > MAX_OBJECTS {
        return None;
    }
    let mut highs: Vec<u8> = objects.iter().map(|o| (o.0 >> 8) as u8).collect();
    highs.dedup();
    if highs.len() > MAX_PAGES {
        return None;
    }
    let n = highs.len();
    let mut t = Tables {
        pages: vec![0; 256],
        bits: vec![[0; 4]; n],
        ranks: vec![[0; 4]; n],
        objects: vec![[0; 4]; n],
        extra: Vec::with_capacity(objects.len()),
    };
    for (k, h) in highs.iter().enumerate() {
        t.pages[usize::from(*h)] = u8::try_from(k + 1).ok()?;
        for w in 0..4u16 {
            let start = (u16::from(*h) << 8) | (w * 64);
            t.ranks[k][usize::from(w)] = u16::try_from(keys.partition_point(|key| key.0 < start)).ok()?;
            t.objects[k][usize::from(w)] = u16::try_from(objects.partition_point(|o| o.0 < start)).ok()?;
        }
    }
    for (number, &(index, first, _)) in objects.iter().enumerate() {
        let page = usize::from(t.pages[usize::from(index >> 8)]) - 1;
        let low = usize::from(index & 0xFF);
        t.bits[page][low / 64] |= 1 << (low % 64);
        // `first` is `rank + k + extra`, with `k` the objects before it in its word.
        let k = number - usize::from(t.objects[page][low / 64]);
        let extra = first - usize::from(t.ranks[page][low / 64]) - k;
        t.extra.push(u8::try_from(extra).unwrap_or(u8::MAX));
    }
    Some(t)
}

/// `OBJECTS` and `LOOKUP` for entries with keys `keys`; `None` past the limits.
///
/// The page tables are computed in the generated code, from the object list, by the runtime's
/// `const fn`s: the generated file holds one index per object instead of the tables.
pub(crate) fn tokens(keys: &[(u16, u8)]) -> Option<TokenStream> {
    let t = build(keys)?;
    let rt = rt();
    let mut objects: Vec<u16> = keys.iter().map(|k| k.0).collect();
    objects.dedup();
    let n_objects = Literal::usize_unsuffixed(objects.len());
    let n_pages = Literal::usize_unsuffixed(t.bits.len());
    let objects = objects.iter().map(|i| lit::hex(u64::from(*i), 4));
    let words = |v: &[[u16; 4]]| -> Vec<TokenStream> {
        v.iter()
            .map(|r| {
                let r = r.iter().map(|x| Literal::u16_unsuffixed(*x));
                quote!([#(#r),*])
            })
            .collect()
    };
    let (ranks, numbers) = (words(&t.ranks), words(&t.objects));
    let extra = t.extra.iter().map(|e| Literal::u8_unsuffixed(*e));
    Some(quote! {
        static OBJECTS: [u16; #n_objects] = [#(#objects),*];

        static LOOKUP: #rt::Lookup = #rt::Lookup {
            pages: #rt::pages(&OBJECTS),
            bits: &#rt::bits::<#n_pages>(&OBJECTS),
            ranks: &[#(#ranks),*],
            objects: &[#(#numbers),*],
            extra: &[#(#extra),*],
            entries: &ROWS,
        };

        /// Where a host finds each object's run of entries in one read (1 KB per page of
        /// 256 indices); empty on a microcontroller, which binary-searches `ROWS`.
        static DIRECT: [u32; #rt::direct_len(#n_pages)] = #rt::direct(&ROWS);
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use od_runtime::__private_v3::{
        Lookup, Row, direct, lookup as runtime_lookup, meta, position as compact, position_direct,
    };
    use od_runtime::od::{AbortCode, Access, DataType};
    use proptest::prelude::*;

    fn leak<T>(v: Vec<T>) -> &'static [T] {
        Box::leak(v.into_boxed_slice())
    }

    /// Both lookups of a dictionary: the compact tables and the host's direct table.
    struct Both {
        tables: Lookup,
        direct: &'static [u32],
    }

    /// The position by every path there is: the compact lookup, the direct one (a host's), the
    /// binary search (a microcontroller's) and the runtime's choice, which must all agree.
    fn position(b: &Both, index: u16, sub: u8) -> Result<usize, AbortCode> {
        let found = compact(&b.tables, index, sub);
        assert_eq!(
            position_direct(&b.tables.pages, b.direct, b.tables.entries, index, sub),
            found,
            "direct {index:#06x} {sub}"
        );
        assert_eq!(runtime_lookup(&b.tables, b.direct, b.tables.entries, index, sub), found);
        // Without a direct table (a microcontroller): a binary search of the entries.
        assert_eq!(runtime_lookup(&b.tables, &[], b.tables.entries, index, sub), found, "sorted {index:#06x} {sub}");
        found
    }

    /// The lookup as the generated code builds it: the runtime's `const fn`s compute the page
    /// table from the object list and the direct table from the entries, and must agree with
    /// [`build`].
    fn lookup(keys: &[(u16, u8)]) -> Both {
        let tables = compact_tables(keys);
        // The largest table there is, cut to the pages this one has (as `direct_len` sizes it).
        let all = Box::new(direct::<{ MAX_PAGES * 256 }>(tables.entries));
        let n = od_runtime::__private_v3::direct_len(tables.bits.len());
        assert!(all[n..].iter().all(|d| *d == 0));
        Both { tables, direct: leak(all[..n].to_vec()) }
    }

    fn compact_tables(keys: &[(u16, u8)]) -> Lookup {
        let t = build(keys).unwrap();
        let mut objects: Vec<u16> = keys.iter().map(|k| k.0).collect();
        objects.dedup();
        let pages: [u8; 256] = t.pages.clone().try_into().unwrap();
        assert_eq!(od_runtime::__private_v3::pages(&objects), pages);
        // The largest page count there is; the generator sizes the arrays exactly.
        let bits = od_runtime::__private_v3::bits::<MAX_PAGES>(&objects);
        assert_eq!(&bits[..t.bits.len()], &t.bits[..]);
        assert!(bits[t.bits.len()..].iter().all(|b| *b == [0; 4]));
        let entries = keys.iter().map(|&(index, sub)| Row {
            index,
            sub,
            data_type: DataType::Unsigned8,
            slot: 0,
            meta: meta(Access::Ro, false, None),
        });
        Lookup {
            pages,
            bits: leak(t.bits),
            ranks: leak(t.ranks),
            objects: leak(t.objects),
            extra: leak(t.extra),
            entries: leak(entries.collect()),
        }
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
    fn objects_past_255_extra_entries_in_their_word_are_searched() {
        // 0x2000 and 0x2001 with 256 entries each: 0x2002's extra is 510, kept as 255 ("more").
        let mut keys: Vec<(u16, u8)> = (0..=255).map(|s| (0x2000, s)).collect();
        keys.extend((0..=255).map(|s| (0x2001, s)));
        keys.extend([(0x2002, 0), (0x2002, 1), (0x2003, 7), (0x2040, 0)]);
        let t = build(&keys).unwrap();
        assert_eq!(t.extra, [0, 255, 255, 255, 0]);
        let l = lookup(&keys);
        for (pos, &(index, sub)) in keys.iter().enumerate() {
            assert_eq!(position(&l, index, sub), Ok(pos));
        }
        assert_eq!(position(&l, 0x2002, 2), Err(AbortCode::NO_SUB_INDEX));
        assert_eq!(position(&l, 0x2003, 0), Err(AbortCode::NO_SUB_INDEX));
        assert_eq!(position(&l, 0x2004, 0), Err(AbortCode::NO_OBJECT));
    }

    #[test]
    fn at_most_65535_objects_in_255_pages() {
        let all: Vec<(u16, u8)> = (0..=u16::MAX).map(|i| (i, 0)).collect();
        assert_eq!(build(&all), None);
        assert_eq!(build(&all[1..]), None, "256 pages");
        assert_eq!(build(&[(0x1000, 0); 65536]), None, "65536 entries");
        // 255 full pages: 65280 objects.
        let l = lookup(&all[256..]);
        assert_eq!(position(&l, 0xFFFF, 0), Ok(255 * 256 - 1));
        assert_eq!(position(&l, 0x0100, 0), Ok(0));
        assert_eq!(position(&l, 0x0040, 0), Err(AbortCode::NO_OBJECT));
        assert_eq!(position(&l, 0x80C1, 0), Ok(0x80C1 - 256));
    }
}
