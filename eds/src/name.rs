//! [`Name`]: the text of a `ParameterName`, kept in place when it is short.
//!
//! A large file has tens of thousands of entries, each with a name, and most names are short
//! (in the corpus 95% of entry names are at most 30 bytes; the elements of a compact array are
//! the array's name and a number). A `String` per name is an allocation per entry, and in a
//! short process every allocation that is not served from memory freed before touches fresh
//! pages. A `Name` keeps up to [`Name::INLINE`] bytes in its own 32 bytes (the room an
//! [`Entry`](crate::Entry) has for it without growing) and only a longer name on the heap.
//!
//! It behaves as the string it holds: it derefs to `str`, compares, orders and hashes as its
//! text, prints as its text and is serialised as a plain string.

use std::borrow::Borrow;
use std::fmt;
use std::hash::{Hash, Hasher};
use std::ops::Deref;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The text of a name (a `ParameterName`), stored in place up to [`Name::INLINE`] bytes.
#[derive(Clone)]
pub struct Name(Repr);

#[derive(Clone)]
enum Repr {
    /// The first `len` bytes of `bytes` are the text (valid UTF-8: they are copied from a `str`
    /// whole, never cut).
    Inline { len: u8, bytes: [u8; Name::INLINE] },
    /// A longer text.
    Heap(Box<str>),
}

impl Name {
    /// The longest text kept in place, in bytes.
    pub const INLINE: usize = 30;

    /// The empty name.
    pub const fn new() -> Self {
        Name(Repr::Inline { len: 0, bytes: [0; Name::INLINE] })
    }

    /// The text of `parts` one after another (a compact array's element: the array's name and
    /// the sub-index), with no intermediate string.
    pub fn concat(parts: &[&str]) -> Self {
        let len: usize = parts.iter().map(|p| p.len()).sum();
        if len <= Self::INLINE {
            let mut bytes = [0; Name::INLINE];
            let mut at = 0;
            for p in parts {
                bytes[at..at + p.len()].copy_from_slice(p.as_bytes());
                at += p.len();
            }
            Name(Repr::Inline { len: len as u8, bytes })
        } else {
            let mut s = String::with_capacity(len);
            for p in parts {
                s.push_str(p);
            }
            Name(Repr::Heap(s.into_boxed_str()))
        }
    }

    /// This name followed by `suffix` (a compact array's element: the array's name and the
    /// sub-index). Short enough, it copies this name's bytes in place and writes the suffix
    /// after them, without reading this name as text.
    #[inline]
    pub fn with_suffix(&self, suffix: &str) -> Self {
        if let Repr::Inline { len, bytes } = &self.0 {
            let at = *len as usize;
            if at + suffix.len() <= Self::INLINE {
                let mut bytes = *bytes;
                for (b, &s) in bytes[at..].iter_mut().zip(suffix.as_bytes()) {
                    *b = s;
                }
                return Name(Repr::Inline { len: (at + suffix.len()) as u8, bytes });
            }
        }
        Name::concat(&[self, suffix])
    }

    /// This name followed by `n` in decimal (a compact array's element: the array's name and
    /// the sub-index), as [`Name::with_suffix`] with the digits of `n`. Short enough, it writes
    /// the digits, from a table of three bytes per number, straight after this name's bytes:
    /// no division, no slice of digits and no loop.
    #[inline]
    pub fn with_number(&self, n: u8) -> Self {
        if let Repr::Inline { len, bytes } = &self.0 {
            let at = *len as usize;
            if at <= Self::INLINE - 3 {
                let (digits, count) = DECIMAL_U8[n as usize];
                let mut bytes = *bytes;
                bytes[at..at + 3].copy_from_slice(&digits);
                return Name(Repr::Inline { len: at as u8 + count, bytes });
            }
        }
        self.with_suffix(crate::decimal::decimal_u8(n))
    }

    /// The text.
    #[inline]
    pub fn as_str(&self) -> &str {
        match &self.0 {
            // Never the default: an inline text is a whole `str` copied byte for byte.
            Repr::Inline { len, bytes } => std::str::from_utf8(&bytes[..*len as usize]).unwrap_or_default(),
            Repr::Heap(s) => s,
        }
    }

    /// The text as a `String`.
    pub fn into_string(self) -> String {
        match self.0 {
            Repr::Heap(s) => s.into_string(),
            Repr::Inline { .. } => self.as_str().to_owned(),
        }
    }

    /// Whether the text is kept in place (no heap block).
    pub fn is_inline(&self) -> bool {
        matches!(self.0, Repr::Inline { .. })
    }
}

/// `b` (at most [`Name::INLINE`] bytes) at the start of the inline storage, zeros after it.
/// Copied as two overlapping blocks of a fixed size (16, 8, 4 or 2 bytes, by the length): a
/// few moves, where a copy of `b.len()` bytes calls `memcpy`.
#[inline(always)]
fn inline_bytes(b: &[u8]) -> [u8; Name::INLINE] {
    let mut bytes = [0; Name::INLINE];
    let n = b.len();
    if n >= 16 {
        bytes[..16].copy_from_slice(&b[..16]);
        bytes[n - 16..n].copy_from_slice(&b[n - 16..]);
    } else if n >= 8 {
        bytes[..8].copy_from_slice(&b[..8]);
        bytes[n - 8..n].copy_from_slice(&b[n - 8..]);
    } else if n >= 4 {
        bytes[..4].copy_from_slice(&b[..4]);
        bytes[n - 4..n].copy_from_slice(&b[n - 4..]);
    } else if n >= 2 {
        bytes[..2].copy_from_slice(&b[..2]);
        bytes[n - 2..n].copy_from_slice(&b[n - 2..]);
    } else if n == 1 {
        bytes[0] = b[0];
    }
    bytes
}

/// The decimal digits of each `u8` (the first ones of three bytes, zeros after them) and how
/// many there are: what [`Name::with_number`] writes.
const DECIMAL_U8: [([u8; 3], u8); 256] = {
    let mut table = [([0; 3], 0); 256];
    let mut n = 0;
    while n < 256 {
        let (hundreds, tens, ones) = (b'0' + (n / 100) as u8, b'0' + (n / 10 % 10) as u8, b'0' + (n % 10) as u8);
        table[n] = if n >= 100 {
            ([hundreds, tens, ones], 3)
        } else if n >= 10 {
            ([tens, ones, 0], 2)
        } else {
            ([ones, 0, 0], 1)
        };
        n += 1;
    }
    table
};

impl Default for Name {
    fn default() -> Self {
        Name::new()
    }
}

impl Deref for Name {
    type Target = str;
    #[inline]
    fn deref(&self) -> &str {
        self.as_str()
    }
}

impl AsRef<str> for Name {
    fn as_ref(&self) -> &str {
        self
    }
}

impl Borrow<str> for Name {
    fn borrow(&self) -> &str {
        self
    }
}

impl From<&str> for Name {
    #[inline]
    fn from(s: &str) -> Self {
        if s.len() <= Self::INLINE {
            Name(Repr::Inline { len: s.len() as u8, bytes: inline_bytes(s.as_bytes()) })
        } else {
            Name(Repr::Heap(s.into()))
        }
    }
}

impl From<&String> for Name {
    fn from(s: &String) -> Self {
        Name::from(s.as_str())
    }
}

impl From<String> for Name {
    fn from(s: String) -> Self {
        if s.len() <= Self::INLINE { Name::from(s.as_str()) } else { Name(Repr::Heap(s.into_boxed_str())) }
    }
}

impl From<Box<str>> for Name {
    fn from(s: Box<str>) -> Self {
        if s.len() <= Self::INLINE { Name::from(&*s) } else { Name(Repr::Heap(s)) }
    }
}

impl From<std::borrow::Cow<'_, str>> for Name {
    fn from(s: std::borrow::Cow<'_, str>) -> Self {
        match s {
            std::borrow::Cow::Borrowed(s) => Name::from(s),
            std::borrow::Cow::Owned(s) => Name::from(s),
        }
    }
}

impl From<Name> for String {
    fn from(n: Name) -> Self {
        n.into_string()
    }
}

impl std::str::FromStr for Name {
    type Err = std::convert::Infallible;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(Name::from(s))
    }
}

impl fmt::Display for Name {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self.as_str(), f)
    }
}

impl fmt::Debug for Name {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

impl PartialEq for Name {
    fn eq(&self, other: &Name) -> bool {
        self.as_str() == other.as_str()
    }
}

impl Eq for Name {}

impl PartialOrd for Name {
    fn partial_cmp(&self, other: &Name) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Name {
    fn cmp(&self, other: &Name) -> std::cmp::Ordering {
        self.as_str().cmp(other.as_str())
    }
}

impl Hash for Name {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.as_str().hash(state)
    }
}

macro_rules! eq_text {
    ($($t:ty),*) => {$(
        impl PartialEq<$t> for Name {
            fn eq(&self, other: &$t) -> bool {
                self.as_str() == AsRef::<str>::as_ref(other)
            }
        }
        impl PartialEq<Name> for $t {
            fn eq(&self, other: &Name) -> bool {
                AsRef::<str>::as_ref(self) == other.as_str()
            }
        }
    )*};
}
eq_text!(str, &str, String);

impl Serialize for Name {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self)
    }
}

impl<'de> Deserialize<'de> for Name {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Text;
        impl serde::de::Visitor<'_> for Text {
            type Value = Name;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a string")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Name, E> {
                Ok(Name::from(v))
            }
            fn visit_string<E: serde::de::Error>(self, v: String) -> Result<Name, E> {
                Ok(Name::from(v))
            }
        }
        deserializer.deserialize_str(Text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::hash_map::DefaultHasher;

    fn hash_of<T: Hash + ?Sized>(t: &T) -> u64 {
        let mut h = DefaultHasher::new();
        t.hash(&mut h);
        h.finish()
    }

    #[test]
    fn size_is_four_words() {
        assert_eq!(std::mem::size_of::<Name>(), 32);
    }

    #[test]
    fn stored_in_place_up_to_the_bound() {
        assert!(Name::from("x".repeat(Name::INLINE)).is_inline());
        assert!(!Name::from("x".repeat(Name::INLINE + 1)).is_inline());
        // A multi-byte character across the bound goes to the heap whole.
        let s = format!("{}é", "x".repeat(Name::INLINE - 1));
        let n = Name::from(s.as_str());
        assert!(!n.is_inline());
        assert_eq!(n, s);
        assert_eq!(Name::new(), "");
    }

    /// The fixed-size copies put every text of every length that fits at the start of the
    /// storage, zeros after it.
    #[test]
    fn inline_bytes_copy_every_length() {
        let text: Vec<u8> = (1..=Name::INLINE as u8).collect();
        for n in 0..=Name::INLINE {
            let bytes = inline_bytes(&text[..n]);
            assert_eq!(&bytes[..n], &text[..n]);
            assert!(bytes[n..].iter().all(|&b| b == 0), "{n}");
            assert_eq!(Name::from(std::str::from_utf8(&text[..n]).unwrap()).len(), n);
        }
    }

    /// `with_number` is `with_suffix` with the number's decimal digits, for every number and
    /// every length of name around the bound of names kept in place (ASCII, and names ending
    /// in a multi-byte character).
    #[test]
    fn with_number_is_with_suffix_of_the_digits() {
        for len in 0..=Name::INLINE + 2 {
            for base in ["x".repeat(len), format!("{}é", "x".repeat(len.saturating_sub(2)))] {
                let name = Name::from(base.as_str());
                for n in 0..=u8::MAX {
                    let got = name.with_number(n);
                    let want = name.with_suffix(&n.to_string());
                    assert_eq!(got.as_str(), format!("{base}{n}"));
                    assert_eq!(got, want);
                    assert_eq!(got.is_inline(), want.is_inline());
                }
            }
        }
    }

    proptest! {
        /// A name behaves as the `String` it was made from, however it was made.
        #[test]
        fn behaves_as_its_string(a in "\\PC{0,40}", b in "\\PC{0,40}", d in "[0-9]{0,3}") {
            let made = [
                Name::from(a.as_str()),
                Name::from(a.clone()),
                Name::from(a.clone().into_boxed_str()),
                a.parse::<Name>().unwrap(),
                Name::concat(&[&a]),
            ];
            for n in &made {
                prop_assert_eq!(n.as_str(), a.as_str());
                prop_assert_eq!(&**n, a.as_str());
                prop_assert_eq!(n.len(), a.len());
                prop_assert!(*n == a && *n == *a.as_str() && *n == a.as_str());
                prop_assert!(a == *n && *a.as_str() == *n && a.as_str() == *n);
                prop_assert_eq!(n.to_string(), a.clone());
                prop_assert_eq!(format!("{n:?}"), format!("{a:?}"));
                prop_assert_eq!(format!("{n:>50}"), format!("{a:>50}"));
                prop_assert_eq!(hash_of(n), hash_of(a.as_str()));
                prop_assert_eq!(n.is_inline(), a.len() <= Name::INLINE);
                prop_assert_eq!(n.clone().into_string(), a.clone());
                prop_assert_eq!(String::from(n.clone()), a.clone());
                prop_assert_eq!(serde_json::to_string(n).unwrap(), serde_json::to_string(&a).unwrap());
                let back: Name = serde_json::from_str(&serde_json::to_string(n).unwrap()).unwrap();
                prop_assert_eq!(&back, n);
            }
            let nb = Name::from(b.as_str());
            prop_assert_eq!(made[0] == nb, a == b);
            prop_assert_eq!(made[0].cmp(&nb), a.cmp(&b));
            prop_assert_eq!(made[0].partial_cmp(&nb), a.partial_cmp(&b));
            for (joined, suffix) in [
                (Name::concat(&[&a, &d]), &d),
                (made[0].with_suffix(&d), &d),
                (made[0].with_suffix(&b), &b),
                (Name::concat(&[&a, &b, &d]), &format!("{b}{d}")),
            ] {
                prop_assert_eq!(joined.as_str(), format!("{a}{suffix}"));
                prop_assert_eq!(joined.is_inline(), a.len() + suffix.len() <= Name::INLINE);
            }
        }
    }
}
