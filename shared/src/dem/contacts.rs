//! The contact list of a world: contacts sorted by key, in parts, each part's keys and
//! contacts in two arrays.
//!
//! A step builds its contacts in key order (body pairs ascending, then wall contacts by wall
//! and body), each chunk of the narrow phase one part of the list, so the list is the chunks'
//! own output, not a copy of it (the copy, 22 ns a contact, was 5 % of a step on the 2000 I_P
//! bed and most of the contact list's half of the step's end on 2 threads). A lookup is a
//! binary search over the parts' last keys, then over a part's keys alone (8 bytes each, so
//! most of the search stays in cache). On a 2000-particle bed the `BTreeMap` this replaced
//! took 4 to 5 % of a step on 2 threads, all of it serial. How the list is cut into parts
//! changes no result: it compares, iterates and indexes as one sequence.

use crate::dem::collision::kept::Packed;
use crate::dem::law::Contact;
use rayon::prelude::*;

/// What a body touches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Partner {
    Body(u32),
    Wall(u32),
}

/// Key of a contact: (partner, body), the body being B (the normal points to it). For body pairs
/// the partner has the lower index.
pub type ContactKey = (Partner, u32);

/// Contacts by key, ascending. Iterates like a map: `for (key, contact) in &contacts`.
///
/// Each contact may also keep its overlap's structure ([`crate::dem::collision::kept`]), to start the next
/// step's contact geometry from. That is not state (the result is the same without it): it is
/// left out of comparisons, and a contact inserted by hand has none. The structures' words lie
/// in one buffer, in key order ([`crate::dem::collision::kept::Structure`] tells why).
#[derive(Clone, Debug, Default)]
pub struct Contacts {
    /// Non-empty parts, each key below the next part's first.
    parts: Vec<Part>,
    /// Where each part starts in the whole list, and its length at the end.
    starts: Vec<usize>,
    kept: Kept,
}

/// A run of the list's contacts: keys ascending, one contact for each.
#[derive(Clone, Debug, Default)]
pub struct Part {
    keys: Vec<ContactKey>,
    values: Vec<Contact>,
    /// A number the part's maker keeps with it (the world: which thread's buffers it came
    /// from); no result depends on it.
    pub tag: usize,
}

impl Part {
    /// Adds a contact after the others.
    ///
    /// # Panics
    /// If `key` is not above the part's last key.
    #[inline]
    pub fn push(&mut self, key: ContactKey, contact: Contact) {
        assert!(self.keys.last() < Some(&key), "{OUT_OF_ORDER}");
        self.keys.push(key);
        self.values.push(contact);
    }

    /// Room for `n` more contacts.
    pub fn reserve(&mut self, n: usize) {
        self.keys.reserve(n);
        self.values.reserve(n);
    }

    pub fn clear(&mut self) {
        self.keys.clear();
        self.values.clear();
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    pub fn keys(&self) -> &[ContactKey] {
        &self.keys
    }

    pub fn values(&self) -> &[Contact] {
        &self.values
    }
}

/// A place in a [`Contacts`] list for a walk over ascending keys ([`Contacts::seek`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Cursor {
    part: usize,
    i: usize,
    index: usize,
}

impl Cursor {
    /// The place in the whole list (the contact's, after a seek that found it).
    pub fn index(&self) -> usize {
        self.index
    }
}

/// Structures in one buffer of words: per contact, where its words start and how many there
/// are (none: no structure). A structure a contact keeps from one step to the next stays where
/// it is; new ones are added at the end, and the buffer is compacted into contact order when
/// more than half of it is no longer anyone's ([`Contacts::keep`]).
#[derive(Clone, Debug, Default)]
pub struct Kept {
    words: Vec<u32>,
    spans: Vec<(u32, u32)>,
}

/// What a contact of the new list keeps ([`Contacts::keep`]).
#[derive(Clone, Copy, Debug)]
pub enum Carry<'a> {
    /// No structure.
    None,
    /// The structure contact `k` of the old list kept.
    Kept(usize),
    /// New words.
    New(&'a [u32]),
}

/// What a list built out of key order panics with (a step that builds one so is a bug).
const OUT_OF_ORDER: &str = "contacts must be built in strictly ascending key order";

/// Below this many words the buffer is not compacted.
const COMPACT_MIN: usize = 1 << 16;

impl Kept {
    /// Room for `count` contacts, none keeping a structure.
    fn none(count: usize) -> Kept {
        Kept {
            words: Vec::new(),
            spans: vec![(0, 0); count],
        }
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
        self.len() == other.len() && self.iter().eq(other.iter())
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
        let mut part = Part::default();
        if par {
            (items.par_iter().map(pair)).unzip_into_vecs(&mut part.keys, &mut part.values);
        } else {
            (part.keys, part.values) = items.iter().map(pair).unzip();
        }
        assert!(part.keys.windows(2).all(|w| w[0] < w[1]), "{OUT_OF_ORDER}");
        let mut out = Contacts::default();
        out.set_parts(vec![part]);
        out
    }

    /// The list made of `parts`, in order (none keeps a structure yet: [`Contacts::keep`]);
    /// the parts it had come back, to fill again.
    ///
    /// # Panics
    /// If the keys are not strictly ascending: a step that builds them otherwise is a bug.
    pub fn set_parts(&mut self, parts: Vec<Part>) -> Vec<Part> {
        let (parts, mut empty): (Vec<Part>, Vec<Part>) =
            parts.into_iter().partition(|p| !p.is_empty());
        // Each part is ascending ([`Part::push`]; [`Contacts::from_sorted`] checks its own).
        let ascending = parts
            .windows(2)
            .all(|w| w[0].keys.last() < w[1].keys.first());
        assert!(ascending, "{OUT_OF_ORDER}");
        let mut old = std::mem::replace(&mut self.parts, parts);
        old.append(&mut empty);
        self.index_parts();
        self.kept = Kept::none(self.len());
        old
    }

    /// `starts` from `parts`.
    fn index_parts(&mut self) {
        self.starts.clear();
        self.starts.push(0);
        for p in &self.parts {
            self.starts
                .push(self.starts.last().copied().unwrap_or(0) + p.len());
        }
    }

    /// The structures the contacts keep, in key order, taken out (none is left kept).
    pub fn take_kept(&mut self) -> Kept {
        let count = self.len();
        std::mem::replace(&mut self.kept, Kept::none(count))
    }

    /// Sets the structures the first `carry.len()` contacts keep, in key order: a kept one
    /// stays where it is in `old`'s buffer (this list's now), a new one is added at its end.
    /// (Copying every structure into a new buffer each step wrote, and first zeroed, 2.3 MB a
    /// step on the 2000 I_P bed, where 99.98 % of them are kept: a fifth of the step's cache
    /// misses in cachegrind.) When more than half of the buffer is no longer anyone's, the
    /// live words are copied into `spare` in contact order (in parallel runs when `par`), and
    /// the buffer they leave is handed back for the next time; else `spare` comes back.
    ///
    /// # Panics
    /// With more structures than contacts, or a kept one `old` does not have.
    pub fn keep(&mut self, old: Kept, carry: &[Carry], spare: Vec<u32>, par: bool) -> Vec<u32> {
        assert!(carry.len() <= self.len(), "more structures than contacts");
        let Kept {
            mut words,
            spans: old_spans,
        } = old;
        let mut spans = Vec::with_capacity(self.len());
        let mut live = 0usize;
        for c in carry {
            let span = match *c {
                Carry::None => (0, 0),
                Carry::Kept(k) => old_spans[k],
                Carry::New(w) => {
                    words.extend_from_slice(w);
                    ((words.len() - w.len()) as u32, w.len() as u32)
                }
            };
            live += span.1 as usize;
            spans.push(span);
        }
        spans.resize(self.len(), (0, 0));
        if words.len() <= COMPACT_MIN.max(2 * live) {
            self.kept = Kept { words, spans };
            return spare;
        }
        // Compacted: the live words in contact order, each run of contacts' words copied into
        // its own part of the new buffer.
        let mut fresh = spare;
        fresh.clear();
        fresh.resize(live, 0);
        let moved: Vec<(u32, u32)> = spans
            .iter()
            .scan(0u32, |at, &(_, len)| {
                let span = if len > 0 { (*at, len) } else { (0, 0) };
                *at += len;
                Some(span)
            })
            .collect();
        const RUN: usize = 512;
        let mut parts = Vec::with_capacity(spans.len().div_ceil(RUN));
        let mut rest = &mut fresh[..];
        for run in spans.chunks(RUN) {
            let len: usize = run.iter().map(|s| s.1 as usize).sum();
            let (part, tail) = rest.split_at_mut(len);
            parts.push((run, part));
            rest = tail;
        }
        let copy = |(run, part): (&[(u32, u32)], &mut [u32])| {
            let mut at = 0;
            for &(start, len) in run {
                let (start, len) = (start as usize, len as usize);
                part[at..at + len].copy_from_slice(&words[start..start + len]);
                at += len;
            }
        };
        if par {
            parts.into_par_iter().for_each(copy);
        } else {
            parts.into_iter().for_each(copy);
        }
        self.kept = Kept {
            words: fresh,
            spans: moved,
        };
        words
    }

    pub fn len(&self) -> usize {
        self.starts.last().copied().unwrap_or(0)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn clear(&mut self) {
        self.parts.clear();
        self.starts.clear();
        self.kept = Kept::default();
    }

    pub fn get(&self, key: &ContactKey) -> Option<&Contact> {
        let at = self.cursor(key);
        let p = self.parts.get(at.part)?;
        (p.keys.get(at.i) == Some(key)).then(|| &p.values[at.i])
    }

    /// Where `key` is or would go: the first position whose key is not below it.
    pub fn lower_bound(&self, key: &ContactKey) -> usize {
        self.cursor(key).index
    }

    /// [`Contacts::lower_bound`] as a cursor, to [`Contacts::seek`] from.
    pub fn cursor(&self, key: &ContactKey) -> Cursor {
        let part = (self.parts).partition_point(|p| p.keys.last().is_some_and(|k| k < key));
        let i = (self.parts.get(part)).map_or(0, |p| p.keys.partition_point(|k| k < key));
        Cursor {
            part,
            i,
            index: self.starts.get(part).copied().unwrap_or(0) + i,
        }
    }

    /// The contact of `key` and the structure it keeps, looked for from `*at` on (at most
    /// `key`'s [`Contacts::cursor`]), which then moves to `key`'s place (the contact's, when
    /// there is one): ascending keys are found by one walk over the list instead of a search
    /// each.
    #[inline]
    pub fn seek(
        &self,
        at: &mut Cursor,
        key: &ContactKey,
    ) -> Option<(&Contact, Option<Packed<'_>>)> {
        loop {
            let p = self.parts.get(at.part)?;
            match p.keys.get(at.i) {
                Some(k) if k < key => {
                    at.i += 1;
                    at.index += 1;
                }
                Some(k) => {
                    return (k == key).then(|| (&p.values[at.i], self.kept.get(at.index)));
                }
                None => {
                    at.part += 1;
                    at.i = 0;
                }
            }
        }
    }

    pub fn contains_key(&self, key: &ContactKey) -> bool {
        self.get(key).is_some()
    }

    /// Inserts or replaces the contact of `key`, returning the one it replaced.
    pub fn insert(&mut self, key: ContactKey, contact: Contact) -> Option<Contact> {
        let mut at = self.cursor(&key);
        if let Some(p) = self.parts.get_mut(at.part) {
            if p.keys.get(at.i) == Some(&key) {
                self.kept.spans[at.index] = (0, 0);
                return Some(std::mem::replace(&mut p.values[at.i], contact));
            }
        }
        if self.parts.is_empty() {
            self.parts.push(Part::default());
        }
        if at.part == self.parts.len() {
            at.part -= 1;
            at.i = self.parts[at.part].len();
        }
        let p = &mut self.parts[at.part];
        p.keys.insert(at.i, key);
        p.values.insert(at.i, contact);
        self.kept.spans.insert(at.index, (0, 0));
        self.index_parts();
        None
    }

    pub fn keys(&self) -> impl Iterator<Item = &ContactKey> + '_ {
        self.parts.iter().flat_map(|p| &p.keys)
    }

    pub fn values(&self) -> impl Iterator<Item = &Contact> + '_ {
        self.parts.iter().flat_map(|p| &p.values)
    }

    pub fn values_mut(&mut self) -> impl Iterator<Item = &mut Contact> + '_ {
        self.parts.iter_mut().flat_map(|p| &mut p.values)
    }

    pub fn iter(&self) -> <&Contacts as IntoIterator>::IntoIter {
        self.into_iter()
    }
}

type PartIter<'a> = std::iter::Zip<std::slice::Iter<'a, ContactKey>, std::slice::Iter<'a, Contact>>;

impl<'a> IntoIterator for &'a Contacts {
    type Item = (&'a ContactKey, &'a Contact);
    type IntoIter =
        std::iter::FlatMap<std::slice::Iter<'a, Part>, PartIter<'a>, fn(&'a Part) -> PartIter<'a>>;

    fn into_iter(self) -> Self::IntoIter {
        fn pairs(p: &Part) -> PartIter<'_> {
            p.keys.iter().zip(&p.values)
        }
        self.parts
            .iter()
            .flat_map(pairs as fn(&'a Part) -> PartIter<'a>)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::contacts::Partner;
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

    #[test]
    fn a_list_in_parts_reads_as_the_list_in_one_piece() {
        let keys: Vec<ContactKey> = (0..400u32)
            .map(|i| (Partner::Body(i / 9), i))
            .chain((0..50u32).map(|i| (Partner::Wall(i / 20), i)))
            .collect();
        let whole = Contacts::from_sorted(&keys, false, |k| *k, |k| contact(k.1 as f64));
        // Cut at uneven places, with empty parts among them (a chunk that found no contact).
        let cuts = [0, 0, 7, 8, 150, 150, 399, 401, 450, 450];
        let parts: Vec<Part> = (cuts.windows(2))
            .map(|w| {
                let mut p = Part::default();
                for k in &keys[w[0]..w[1]] {
                    p.push(*k, contact(k.1 as f64));
                }
                p
            })
            .collect();
        let mut cut = Contacts::new();
        assert!(cut.set_parts(parts).iter().all(|p| p.is_empty()));
        assert_eq!(cut, whole);
        assert_eq!(cut.len(), 450);
        assert!(cut.keys().eq(whole.keys()) && cut.values().eq(whole.values()));
        // Every key, and every gap between keys, is found at the same place.
        let probes =
            (keys.iter().copied()).chain([(Partner::Body(3), 1000), (Partner::Wall(9), 0)]);
        let mut at = cut.cursor(&keys[0]);
        for k in probes {
            assert_eq!(cut.lower_bound(&k), whole.lower_bound(&k), "{k:?}");
            assert_eq!(cut.get(&k), whole.get(&k), "{k:?}");
        }
        // One walk over ascending keys finds each contact at its place in the whole list.
        for (n, k) in keys.iter().enumerate().step_by(3) {
            let (c, _) = cut.seek(&mut at, k).expect("a listed key");
            assert_eq!((c.depth, at.index()), (k.1 as f64, n));
        }
        // An insert at a part's end, between parts and after all keeps the order.
        let mut a = cut.clone();
        let mut b = whole.clone();
        for k in [
            (Partner::Body(0), 401),
            (Partner::Body(44), 900),
            (Partner::Wall(7), 1),
        ] {
            assert!(a.insert(k, contact(-1.0)).is_none());
            assert!(b.insert(k, contact(-1.0)).is_none());
        }
        assert_eq!(a, b);
        assert!(a.keys().zip(a.keys().skip(1)).all(|(x, y)| x < y));
        assert_eq!(a.len(), 453);
    }

    #[test]
    #[should_panic(expected = "ascending key order")]
    fn parts_out_of_key_order_are_refused() {
        let mut parts = [Part::default(), Part::default()];
        parts[0].push((Partner::Body(5), 9), contact(0.0));
        parts[1].push((Partner::Body(1), 2), contact(0.0));
        Contacts::new().set_parts(parts.to_vec());
    }

    #[test]
    #[should_panic(expected = "ascending key order")]
    fn a_part_refuses_a_key_below_its_last() {
        let mut p = Part::default();
        p.push((Partner::Body(5), 9), contact(0.0));
        p.push((Partner::Body(5), 9), contact(0.0));
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
        let carry: Vec<Carry> = (kept.iter())
            .map(|k| k.as_deref().map_or(Carry::None, Carry::New))
            .collect();
        let mut lists = [true, false].map(|par| {
            let mut c = Contacts::from_sorted(&items, par, |k| *k, |_| contact(0.0));
            let spare = c.keep(Kept::default(), &carry, vec![7; 3], par);
            assert_eq!(spare, vec![7; 3], "under the minimum: not compacted");
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
    fn kept_structures_stay_put_until_most_of_the_buffer_is_garbage() {
        // 3000 contacts of 40 words: 120 000 words, over the compaction minimum.
        let items: Vec<ContactKey> = (0..3000u32).map(|i| (Partner::Body(0), i + 1)).collect();
        let first: Vec<Vec<u32>> = (0..3000u32).map(|i| vec![i; 40]).collect();
        let mut c = Contacts::from_sorted(&items, false, |k| *k, |_| contact(0.0));
        let new: Vec<Carry> = first.iter().map(|w| Carry::New(w)).collect();
        c.keep(Kept::default(), &new, Vec::new(), false);
        for par in [false, true] {
            // Next step: every contact keeps its structure but one in ten, which gets new words.
            let step = |c: &mut Contacts, mark: u32| {
                let old = c.take_kept();
                let fresh: Vec<Vec<u32>> = (0..3000u32).map(|i| vec![mark + i; 40]).collect();
                let carry: Vec<Carry> = (0..3000)
                    .map(|k| {
                        if k % 10 == 0 {
                            Carry::New(&fresh[k])
                        } else {
                            Carry::Kept(k)
                        }
                    })
                    .collect();
                let before = old.words.len();
                c.keep(old, &carry, Vec::new(), par);
                (before, c.kept.words.len())
            };
            let mut d = c.clone();
            let (before, after) = step(&mut d, 1_000_000);
            assert_eq!(
                after,
                before + 300 * 40,
                "kept words stay, new ones are added"
            );
            assert_eq!(d.kept.get(0).unwrap().words(), &[1_000_000; 40][..]);
            assert_eq!(d.kept.get(1).unwrap().words(), &[1; 40][..]);
            // Ten more such steps: the buffer is compacted on the way, and every contact still
            // has its own words.
            let (mut longest, mut compactions) = (0, 0);
            for s in 2..12u32 {
                let (before, after) = step(&mut d, s * 1_000_000);
                longest = longest.max(after);
                if after < before {
                    compactions += 1;
                    assert_eq!(after, 120_000, "compacted to the live words");
                }
            }
            assert_eq!(compactions, 1);
            assert!(longest <= 2 * 120_000, "{longest} words for 120 000 live");
            assert_eq!(d.kept.get(0).unwrap().words(), &[11_000_000; 40][..]);
            assert_eq!(d.kept.get(10).unwrap().words(), &[11_000_010; 40][..]);
            assert_eq!(d.kept.get(7).unwrap().words(), &[7; 40][..]);
        }
    }

    #[test]
    #[should_panic(expected = "ascending key order")]
    fn a_list_out_of_key_order_is_refused() {
        let items = [(Partner::Wall(0), 1u32), (Partner::Body(3), 0)];
        Contacts::from_sorted(&items, false, |k| *k, |_| contact(0.0));
    }
}
