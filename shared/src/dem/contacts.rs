//! The contact list of a world: contacts sorted by key, keys and contacts in two arrays.
//!
//! A step builds its contacts in key order (body pairs ascending, then wall contacts by wall
//! and body), so the list is rebuilt by a parallel copy instead of a tree's serial inserts, and
//! a lookup is a binary search over the keys alone (8 bytes each, so most of the search stays in
//! cache). On a 2000-particle bed the `BTreeMap` this replaces took 4 to 5 % of a step on 2
//! threads, all of it serial.

use super::structure::Packed;
use super::world::{Contact, ContactKey};
use rayon::prelude::*;

/// Contacts by key, ascending. Iterates like a map: `for (key, contact) in &contacts`.
///
/// Each contact may also keep its overlap's structure ([`super::structure`]), to start the next
/// step's contact geometry from. That is not state (the result is the same without it): it is
/// left out of comparisons, and a contact inserted by hand has none. The structures' words lie
/// in one buffer, in key order ([`super::structure::Structure`] tells why).
#[derive(Clone, Debug, Default)]
pub struct Contacts {
    keys: Vec<ContactKey>,
    values: Vec<Contact>,
    kept: Kept,
}

/// Structures in one buffer of words: per contact, where its words start and how many there
/// are (none: no structure).
#[derive(Clone, Debug, Default)]
pub struct Kept {
    words: Vec<u32>,
    spans: Vec<(u32, u32)>,
}

impl Kept {
    /// Room for `count` contacts, none keeping a structure.
    fn none(count: usize) -> Kept {
        Kept {
            words: Vec::new(),
            spans: vec![(0, 0); count],
        }
    }

    /// The buffer, for the next [`Contacts::keep`] to fill (a new buffer each step faulted in
    /// 2 MiB of fresh pages on the 2000 I_P bed).
    pub fn into_buffer(self) -> Vec<u32> {
        self.words
    }

    /// The structure of contact `k`, if it keeps one.
    pub fn get(&self, k: usize) -> Option<Packed<'_>> {
        let &(start, len) = self.spans.get(k)?;
        let (start, len) = (start as usize, len as usize);
        (len > 0).then(|| Packed::new(&self.words[start..start + len]))
    }
}

impl PartialEq for Contacts {
    fn eq(&self, other: &Contacts) -> bool {
        self.keys == other.keys && self.values == other.values
    }
}

impl Contacts {
    pub fn new() -> Contacts {
        Contacts::default()
    }

    /// The list from `(key, contact)` items already in ascending key order, each key once.
    /// Copies in parallel when `par`.
    ///
    /// # Panics
    /// If the keys are not strictly ascending: a step that builds them otherwise is a bug.
    /// No contact keeps a structure yet ([`Contacts::keep`]).
    pub fn from_sorted<T: Sync>(
        items: &[T],
        par: bool,
        key: impl Fn(&T) -> ContactKey + Sync + Send,
        contact: impl Fn(&T) -> Contact + Sync + Send,
    ) -> Contacts {
        let pair = |t: &T| (key(t), contact(t));
        let (keys, values): (Vec<ContactKey>, Vec<Contact>) = if par {
            items.par_iter().map(pair).unzip()
        } else {
            items.iter().map(pair).unzip()
        };
        assert!(
            keys.windows(2).all(|w| w[0] < w[1]),
            "contacts must be built in strictly ascending key order"
        );
        let kept = Kept::none(keys.len());
        Contacts { keys, values, kept }
    }

    /// The structures the contacts keep, in key order, taken out (none is left kept).
    pub fn take_kept(&mut self) -> Kept {
        std::mem::replace(&mut self.kept, Kept::none(self.keys.len()))
    }

    /// Sets the structures the first `kept.len()` contacts keep, in key order, copying their
    /// words into `buffer` (in parallel runs when `par`: serial, the copy sat in a force
    /// assembly that had grown to 13-14 % of a 2-thread step on the 2000 and 5000 I_P beds).
    ///
    /// # Panics
    /// With more structures than contacts.
    pub fn keep(&mut self, kept: &[Option<&[u32]>], buffer: Vec<u32>, par: bool) {
        let Kept { words, spans } = &mut self.kept;
        assert!(kept.len() <= spans.len(), "more structures than contacts");
        let mut end = 0u32;
        for (slot, s) in spans.iter_mut().zip(kept) {
            let len = s.map_or(0, |w| w.len() as u32);
            *slot = if len > 0 { (end, len) } else { (0, 0) };
            end += len;
        }
        *words = buffer;
        words.clear();
        words.resize(end as usize, 0);
        // The words of each run of contacts go to their own part of the buffer.
        const RUN: usize = 512;
        let mut parts = Vec::with_capacity(kept.len().div_ceil(RUN));
        let mut rest = &mut words[..];
        for run in kept.chunks(RUN) {
            let len: usize = run.iter().map(|s| s.map_or(0, <[u32]>::len)).sum();
            let (part, tail) = rest.split_at_mut(len);
            parts.push((run, part));
            rest = tail;
        }
        let copy = |(run, part): (&[Option<&[u32]>], &mut [u32])| {
            let mut at = 0;
            for w in run.iter().flatten() {
                part[at..at + w.len()].copy_from_slice(w);
                at += w.len();
            }
        };
        if par {
            parts.into_par_iter().for_each(copy);
        } else {
            parts.into_iter().for_each(copy);
        }
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    pub fn clear(&mut self) {
        self.keys.clear();
        self.values.clear();
        self.kept = Kept::default();
    }

    pub fn get(&self, key: &ContactKey) -> Option<&Contact> {
        self.keys.binary_search(key).ok().map(|k| &self.values[k])
    }

    /// Where `key` is or would go: the first position whose key is not below it.
    pub fn lower_bound(&self, key: &ContactKey) -> usize {
        self.keys.partition_point(|k| k < key)
    }

    /// The contact of `key` and the structure it keeps, looked for from position `*at` on (at
    /// most `key`'s [`Contacts::lower_bound`]), which then moves to `key`'s place (the contact's
    /// position, when there is one): ascending keys are found by one walk over the list instead
    /// of a search each.
    pub fn seek(&self, at: &mut usize, key: &ContactKey) -> Option<(&Contact, Option<Packed<'_>>)> {
        while self.keys.get(*at).is_some_and(|k| k < key) {
            *at += 1;
        }
        (self.keys.get(*at) == Some(key)).then(|| (&self.values[*at], self.kept.get(*at)))
    }

    pub fn contains_key(&self, key: &ContactKey) -> bool {
        self.keys.binary_search(key).is_ok()
    }

    /// Inserts or replaces the contact of `key`, returning the one it replaced.
    pub fn insert(&mut self, key: ContactKey, contact: Contact) -> Option<Contact> {
        match self.keys.binary_search(&key) {
            Ok(k) => {
                self.kept.spans[k] = (0, 0);
                Some(std::mem::replace(&mut self.values[k], contact))
            }
            Err(k) => {
                self.keys.insert(k, key);
                self.values.insert(k, contact);
                self.kept.spans.insert(k, (0, 0));
                None
            }
        }
    }

    pub fn keys(&self) -> std::slice::Iter<'_, ContactKey> {
        self.keys.iter()
    }

    pub fn values(&self) -> std::slice::Iter<'_, Contact> {
        self.values.iter()
    }

    pub fn values_mut(&mut self) -> std::slice::IterMut<'_, Contact> {
        self.values.iter_mut()
    }

    pub fn iter(&self) -> <&Contacts as IntoIterator>::IntoIter {
        self.into_iter()
    }
}

impl<'a> IntoIterator for &'a Contacts {
    type Item = (&'a ContactKey, &'a Contact);
    type IntoIter = std::iter::Zip<std::slice::Iter<'a, ContactKey>, std::slice::Iter<'a, Contact>>;

    fn into_iter(self) -> Self::IntoIter {
        self.keys.iter().zip(self.values.iter())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::world::Partner;
    use crate::math::Vec3;

    fn contact(depth: f64) -> Contact {
        Contact {
            normal: Vec3::z(),
            point: Vec3::zeros(),
            depth,
            normal_force: 0.0,
            potential: 0.0,
            shear: Vec3::zeros(),
            sliding: false,
        }
    }

    #[test]
    fn inserts_keep_the_keys_ascending_and_replace_a_known_key() {
        let mut c = Contacts::new();
        let keys = [
            (Partner::Wall(1), 0),
            (Partner::Body(2), 5),
            (Partner::Wall(0), 3),
            (Partner::Body(0), 7),
            (Partner::Body(2), 3),
        ];
        for (n, k) in keys.iter().enumerate() {
            assert!(c.insert(*k, contact(n as f64)).is_none());
        }
        let old = c.insert((Partner::Body(2), 5), contact(9.0));
        assert_eq!(old.map(|o| o.depth), Some(1.0));
        let got: Vec<_> = c.iter().map(|(k, v)| (*k, v.depth)).collect();
        assert_eq!(
            got,
            vec![
                ((Partner::Body(0), 7), 3.0),
                ((Partner::Body(2), 3), 4.0),
                ((Partner::Body(2), 5), 9.0),
                ((Partner::Wall(0), 3), 2.0),
                ((Partner::Wall(1), 0), 0.0),
            ]
        );
        assert_eq!(c.get(&(Partner::Wall(0), 3)).map(|v| v.depth), Some(2.0));
        assert!(c.get(&(Partner::Wall(0), 4)).is_none());
        assert!(c.contains_key(&(Partner::Body(0), 7)));
    }

    #[test]
    fn a_list_built_in_parallel_equals_the_serial_one() {
        let items: Vec<(ContactKey, f64)> = (0..500u32)
            .map(|i| ((Partner::Body(i / 7), i), i as f64))
            .chain((0..300u32).map(|i| ((Partner::Wall(i / 100), i), -(i as f64))))
            .collect();
        let build = |par| Contacts::from_sorted(&items, par, |t| t.0, |t| contact(t.1));
        let (a, b) = (build(true), build(false));
        assert_eq!(a, b);
        assert_eq!(a.len(), 800);
        assert_eq!(
            a.get(&(Partner::Wall(2), 250)).map(|v| v.depth),
            Some(-250.0)
        );
    }

    /// Words of a made-up structure `k` words long, starting from `k`.
    fn words(k: u32) -> Vec<u32> {
        (k..2 * k).collect()
    }

    #[test]
    fn kept_structures_come_back_in_contact_order_serial_or_parallel() {
        let items: Vec<ContactKey> = (0..1500u32).map(|i| (Partner::Body(i / 5), i)).collect();
        // Every third contact keeps nothing; the rest 1 to 40 words.
        let kept: Vec<Option<Vec<u32>>> = (0..1400u32)
            .map(|i| (i % 3 != 0).then(|| words(1 + i % 40)))
            .collect();
        let refs: Vec<Option<&[u32]>> = kept.iter().map(|k| k.as_deref()).collect();
        let mut lists = [true, false].map(|par| {
            let mut c = Contacts::from_sorted(&items, par, |k| *k, |_| contact(0.0));
            c.keep(&refs, vec![7; 3], par);
            c
        });
        for c in &lists {
            for (k, want) in kept.iter().enumerate() {
                let got = c.kept.get(k).map(|p| p.words().to_vec());
                assert_eq!(got.as_ref(), want.as_ref(), "contact {k}");
            }
            // Past the structures handed over: none.
            assert!((1400..1500).all(|k| c.kept.get(k).is_none()));
        }
        // Taken out, a list keeps none; replacing a contact drops its structure.
        let [a, b] = &mut lists;
        let old = a.take_kept();
        assert!(a.kept.get(1).is_none() && old.get(1).is_some());
        assert!(b.kept.get(1).is_some());
        b.insert((Partner::Body(0), 1), contact(1.0));
        assert!(b.kept.get(1).is_none());
        assert!(b.kept.get(2).is_some());
    }

    #[test]
    #[should_panic(expected = "ascending key order")]
    fn a_list_out_of_key_order_is_refused() {
        let items = [(Partner::Wall(0), 1u32), (Partner::Body(3), 0)];
        Contacts::from_sorted(&items, false, |k| *k, |_| contact(0.0));
    }
}
