//! A set of inner nodes of the vertex quadtree as a paged bitset: what both ends keep of a cut.
//!
//! A membership test is a bit test, not a hash look-up, and the memory follows the set, not the
//! terrain: a page holds the bits of a 16 x 16 block of nodes of one level, and a level keeps a
//! dense directory of 256 x 256-node superpages (a few hundred entries even on a 16385² grid),
//! each a table of its 256 pages. Pages and superpages are allocated when their first node enters
//! and freed when their last one leaves.
//!
//! Slot 0 of the superpage and page tables is an all-zero sentinel that is never written, so a
//! look-up is three dependent loads and no branch on absent pages.
//!
//! A set made [`NodeSet::tagged`] also keeps a 4-bit tag per node of its pages, for its owner's
//! bookkeeping (the server's schedule keeps a generation there).
//!
//! Within a page the bits are in Morton order, so the four children of a node (which lie in one
//! page of the next level) are one aligned nibble: [`NodeSet::children_mask`] reads them at once,
//! child `k` (as in [`NodeId::child`]) at bit `k`.

use crate::prefetch::prefetch;
use crate::tree::{NodeId, TreeShape};

mod morton;

/// log2 of a page's side in nodes.
const PAGE_SHIFT: u32 = 4;
/// log2 of a superpage's side in nodes.
const SUPER_SHIFT: u32 = 8;
/// Pages per superpage.
const SUPER_PAGES: usize = 1 << (2 * (SUPER_SHIFT - PAGE_SHIFT));

/// `v`'s low four bits spread to the even bits of a byte.
const fn spread4(v: u32) -> u32 {
    (v & 1) | ((v & 2) << 1) | ((v & 4) << 2) | ((v & 8) << 3)
}

/// [`morton8`] of every `(x, y)` of a page, by `x | y << 4`: one load where the spreading
/// took about twenty instructions per look-up.
const MORTON8: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = (spread4(i as u32 & 15) | spread4(i as u32 >> 4) << 1) as u8;
        i += 1;
    }
    t
};

/// Morton code of `(x, y)` within a page (their low four bits): x in the even bits.
#[inline]
fn morton8(x: u32, y: u32) -> u32 {
    u32::from(MORTON8[((x & 15) | (y & 15) << 4) as usize])
}

/// Where `node`'s page lies in its superpage's table.
#[inline]
fn page_in_super(node: NodeId) -> usize {
    let mask = (1 << (SUPER_SHIFT - PAGE_SHIFT)) - 1;
    (((node.y >> PAGE_SHIFT) & mask) << (SUPER_SHIFT - PAGE_SHIFT)
        | ((node.x >> PAGE_SHIFT) & mask)) as usize
}

/// The inverse of [`morton8`]'s even bits.
const fn compact4(m: u32) -> u32 {
    (m & 1) | ((m >> 1) & 2) | ((m >> 2) & 4) | ((m >> 3) & 8)
}

/// Pushes `v` onto `vec`, growing it by an eighth when full instead of doubling it: a set's
/// tables hold its peak in pages, and doubling would let a quarter to a half of that be unused
/// capacity. Still amortised constant time.
fn push_lean<T>(vec: &mut Vec<T>, v: T) {
    if vec.len() == vec.capacity() {
        vec.reserve_exact(vec.len() / 8 + 4);
    }
    vec.push(v);
}

/// One level's directory of superpages.
#[derive(Clone, Debug, Default)]
struct Level {
    /// Superpages per row.
    cols: u32,
    /// Superpage slot of each superpage, row-major; empty until the level's first node.
    dir: Vec<u32>,
    /// Nodes per row of this level, for dense indices.
    width: u32,
    /// Dense index of the level's first node ([`TreeShape::level_offset`]).
    offset: u64,
}

impl Level {
    /// Where `node`'s superpage lies in the directory (`node` must be of this level's size).
    #[inline]
    fn super_index(&self, node: NodeId) -> usize {
        ((node.y >> SUPER_SHIFT) * self.cols + (node.x >> SUPER_SHIFT)) as usize
    }
}

/// A set of inner nodes: see the module docs.
#[derive(Clone, Debug, Default)]
pub struct NodeSet {
    /// Per level.
    levels: Vec<Level>,
    /// Page slot of each page of a superpage; slot 0 is the all-zero sentinel.
    supers: Vec<[u32; SUPER_PAGES]>,
    /// Live pages per superpage.
    super_live: Vec<u16>,
    /// The bits; slot 0 is the all-zero sentinel.
    pages: Vec<[u64; 4]>,
    /// A 4-bit tag per node of each page (two a byte), by page slot, when the set is tagged.
    tags: Vec<[u8; 128]>,
    /// Whether pages carry tags.
    tagged: bool,
    /// Set bits per page.
    page_live: Vec<u16>,
    /// Freed superpage and page slots, reused first.
    free_supers: Vec<u32>,
    free_pages: Vec<u32>,
    /// Number of nodes in the set.
    len: usize,
}

impl NodeSet {
    /// An empty set whose nodes carry a byte each ([`NodeSet::tag`]).
    pub fn tagged() -> NodeSet {
        NodeSet {
            tagged: true,
            ..NodeSet::default()
        }
    }

    /// The tag of `node` (0 for nodes outside the set or an untagged set). A node's tag is
    /// kept until its page is freed; a reused page starts at 0.
    #[inline]
    pub fn tag(&self, node: NodeId) -> u8 {
        if !self.tagged || self.supers.is_empty() {
            return 0;
        }
        let (page, bit) = self.locate(node);
        self.tags[page][(bit >> 1) as usize] >> ((bit & 1) * 4) & 15
    }

    /// Sets the tag of `node` to `tag`'s low four bits; `node` must be in the set (no effect
    /// otherwise).
    #[inline]
    pub fn set_tag(&mut self, node: NodeId, tag: u8) {
        if !self.tagged || self.supers.is_empty() {
            return;
        }
        let (page, bit) = self.locate(node);
        if page != 0 {
            let shift = (bit & 1) * 4;
            let t = &mut self.tags[page][(bit >> 1) as usize];
            *t = (*t & !(15 << shift)) | (tag & 15) << shift;
        }
    }

    /// Adds one (modulo 16) to the tag of `node`, which must be in the set, and returns the new
    /// tag (0 for an untagged set).
    #[inline]
    pub fn bump_tag(&mut self, node: NodeId) -> u8 {
        if !self.tagged || self.supers.is_empty() {
            return 0;
        }
        let (page, bit) = self.locate(node);
        if page == 0 {
            return 0;
        }
        let shift = (bit & 1) * 4;
        let t = &mut self.tags[page][(bit >> 1) as usize];
        let v = (*t >> shift).wrapping_add(1) & 15;
        *t = (*t & !(15 << shift)) | v << shift;
        v
    }

    /// Number of nodes in the set.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Bytes of memory held: directories, superpage tables and pages.
    pub fn memory_bytes(&self) -> usize {
        let dirs: usize = self.levels.iter().map(|l| l.dir.capacity() * 4).sum();
        dirs + self.supers.capacity() * (SUPER_PAGES * 4 + 2)
            + self.pages.capacity() * (32 + 2)
            + self.tags.capacity() * 128
            + (self.free_supers.capacity() + self.free_pages.capacity()) * 4
            + self.levels.capacity() * std::mem::size_of::<Level>()
    }

    /// The page slot holding `node` (0 when absent) and the node's bit in it.
    #[inline]
    fn locate(&self, node: NodeId) -> (usize, u32) {
        let Some(level) = self.levels.get(node.level as usize) else {
            return (0, 0);
        };
        let (sx, sy) = (node.x >> SUPER_SHIFT, node.y >> SUPER_SHIFT);
        let sup = if sx < level.cols {
            level
                .dir
                .get((sy * level.cols + sx) as usize)
                .copied()
                .unwrap_or(0)
        } else {
            0
        };
        (
            self.supers[sup as usize][page_in_super(node)] as usize,
            morton8(node.x, node.y),
        )
    }

    /// Prefetches the page holding `node` and, in a tagged set, its tag: what
    /// [`NodeSet::member_tag`] reads, a few items of work before it does.
    #[inline(always)]
    pub fn prefetch(&self, node: NodeId) {
        if self.supers.is_empty() {
            return;
        }
        let (page, bit) = self.locate(node);
        prefetch(&self.pages[page]);
        if self.tagged {
            prefetch(&self.tags[page][(bit >> 1) as usize]);
        }
    }

    /// Whether `node` is in the set.
    #[inline]
    pub fn contains(&self, node: NodeId) -> bool {
        if self.supers.is_empty() {
            return false;
        }
        let (page, bit) = self.locate(node);
        self.pages[page][(bit >> 6) as usize] >> (bit & 63) & 1 != 0
    }

    /// The tag of `node` when it is in the set (0 for an untagged set), from one look-up.
    #[inline]
    pub fn member_tag(&self, node: NodeId) -> Option<u8> {
        if self.supers.is_empty() {
            return None;
        }
        let (page, bit) = self.locate(node);
        if self.pages[page][(bit >> 6) as usize] >> (bit & 63) & 1 == 0 {
            return None;
        }
        Some(if self.tagged {
            self.tags[page][(bit >> 1) as usize] >> ((bit & 1) * 4) & 15
        } else {
            0
        })
    }

    /// Which of `node`'s children are in the set: bit `k` for child `k`.
    #[inline]
    pub fn children_mask(&self, node: NodeId) -> u8 {
        if self.supers.is_empty() {
            return 0;
        }
        let first = node.child(0);
        let (page, bit) = self.locate(first);
        (self.pages[page][(bit >> 6) as usize] >> (bit & 63) & 15) as u8
    }

    /// Which of `node`'s grandchildren are in the set: nibble `k` is
    /// [`NodeSet::children_mask`] of child `k`. The 4 x 4 block of grandchildren is 16 aligned
    /// bits of one page, so this is one look-up where the four children's masks are four.
    #[inline]
    pub fn grandchildren_mask(&self, node: NodeId) -> u16 {
        if self.supers.is_empty() {
            return 0;
        }
        let first = node.child(0).child(0);
        let (page, bit) = self.locate(first);
        (self.pages[page][(bit >> 6) as usize] >> (bit & 63) & 0xffff) as u16
    }

    /// Adds `node`, an existing node of `shape`; returns whether it was absent.
    pub fn insert(&mut self, shape: &TreeShape, node: NodeId) -> bool {
        if self.supers.is_empty() {
            // The sentinels.
            push_lean(&mut self.supers, [0; SUPER_PAGES]);
            push_lean(&mut self.super_live, 0);
            push_lean(&mut self.pages, [0; 4]);
            push_lean(&mut self.page_live, 0);
            if self.tagged {
                push_lean(&mut self.tags, [0; 128]);
            }
        }
        let l = node.level as usize;
        while self.levels.len() <= l {
            let level = self.levels.len() as u8;
            let (w, _) = shape.level_dims(level);
            self.levels.push(Level {
                cols: w.div_ceil(1 << SUPER_SHIFT),
                dir: Vec::new(),
                width: w,
                offset: shape.level_offset(level),
            });
        }
        if self.levels[l].dir.is_empty() {
            let (w, h) = shape.level_dims(node.level);
            let n = w.div_ceil(1 << SUPER_SHIFT) as usize * h.div_ceil(1 << SUPER_SHIFT) as usize;
            self.levels[l].dir = vec![0; n];
        }
        let level = &self.levels[l];
        let d = level.super_index(node);
        let mut sup = level.dir[d];
        if sup == 0 {
            sup = match self.free_supers.pop() {
                Some(s) => s,
                None => {
                    push_lean(&mut self.supers, [0; SUPER_PAGES]);
                    push_lean(&mut self.super_live, 0);
                    self.supers.len() as u32 - 1
                }
            };
            self.levels[l].dir[d] = sup;
        }
        let p = page_in_super(node);
        let mut page = self.supers[sup as usize][p];
        if page == 0 {
            page = match self.free_pages.pop() {
                Some(s) => s,
                None => {
                    push_lean(&mut self.pages, [0; 4]);
                    push_lean(&mut self.page_live, 0);
                    if self.tagged {
                        push_lean(&mut self.tags, [0; 128]);
                    }
                    self.pages.len() as u32 - 1
                }
            };
            if self.tagged {
                self.tags[page as usize] = [0; 128];
            }
            self.supers[sup as usize][p] = page;
            self.super_live[sup as usize] += 1;
        }
        let bit = morton8(node.x, node.y);
        let word = &mut self.pages[page as usize][(bit >> 6) as usize];
        let m = 1u64 << (bit & 63);
        if *word & m != 0 {
            return false;
        }
        *word |= m;
        self.page_live[page as usize] += 1;
        self.len += 1;
        true
    }

    /// Removes `node`; returns whether it was present.
    pub fn remove(&mut self, node: NodeId) -> bool {
        if self.supers.is_empty() {
            return false;
        }
        let (page, bit) = self.locate(node);
        if page == 0 {
            return false;
        }
        let word = &mut self.pages[page][(bit >> 6) as usize];
        let m = 1u64 << (bit & 63);
        if *word & m == 0 {
            return false;
        }
        *word &= !m;
        self.len -= 1;
        self.page_live[page] -= 1;
        if self.page_live[page] == 0 {
            self.free_page(node, page as u32);
        }
        true
    }

    /// Returns `page`, now empty, to the free list, and its superpage too if that empties.
    fn free_page(&mut self, node: NodeId, page: u32) {
        let level = &mut self.levels[node.level as usize];
        let d = level.super_index(node);
        let sup = level.dir[d] as usize;
        let p = page_in_super(node);
        self.supers[sup][p] = 0;
        self.free_pages.push(page);
        self.super_live[sup] -= 1;
        if self.super_live[sup] == 0 {
            level.dir[d] = 0;
            self.free_supers.push(sup as u32);
        }
    }

    /// Every node of the set, level by level, in no set order within a level.
    pub fn iter(&self) -> impl Iterator<Item = NodeId> + '_ {
        self.levels.iter().enumerate().flat_map(move |(l, level)| {
            level
                .dir
                .iter()
                .enumerate()
                .filter(|&(_, &s)| s != 0)
                .flat_map(move |(d, &s)| {
                    let sx = (d as u32 % level.cols) << SUPER_SHIFT;
                    let sy = (d as u32 / level.cols) << SUPER_SHIFT;
                    self.supers[s as usize]
                        .iter()
                        .enumerate()
                        .filter(|&(_, &p)| p != 0)
                        .flat_map(move |(pi, &p)| {
                            let per_row = 1 << (SUPER_SHIFT - PAGE_SHIFT);
                            let px = sx + ((pi as u32 % per_row) << PAGE_SHIFT);
                            let py = sy + ((pi as u32 / per_row) << PAGE_SHIFT);
                            self.pages[p as usize].iter().enumerate().flat_map(
                                move |(wi, &word)| {
                                    Bits(word).map(move |b| {
                                        let m = (wi as u32) << 6 | b;
                                        NodeId {
                                            level: l as u8,
                                            x: px + compact4(m),
                                            y: py + compact4(m >> 1),
                                        }
                                    })
                                },
                            )
                        })
                })
        })
    }

    /// The dense index ([`TreeShape::index`]) of a node of the set's tree, without the shape.
    pub fn dense_index(&self, node: NodeId) -> u64 {
        let level = &self.levels[node.level as usize];
        level.offset + node.y as u64 * level.width as u64 + node.x as u64
    }
}

/// The set bits of a word, lowest first.
struct Bits(u64);

impl Iterator for Bits {
    type Item = u32;

    fn next(&mut self) -> Option<u32> {
        if self.0 == 0 {
            return None;
        }
        let b = self.0.trailing_zeros();
        self.0 &= self.0 - 1;
        Some(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeSet;

    fn inner_node(shape: &TreeShape, level: u8, x: u32, y: u32) -> NodeId {
        let (w, h) = shape.level_dims(level);
        NodeId {
            level,
            x: x % w,
            y: y % h,
        }
    }

    proptest! {
        #[test]
        fn behaves_as_a_set(w in 2u32..1200, h in 2u32..1200,
                            ops in proptest::collection::vec((any::<bool>(), 0u8..16, any::<u32>(), any::<u32>()), 1..400)) {
            let shape = TreeShape::new(w, h).unwrap();
            let mut set = NodeSet::tagged();
            let mut truth = BTreeSet::new();
            for (add, l, x, y) in ops {
                let n = inner_node(&shape, l % shape.depth(), x, y);
                if add {
                    prop_assert_eq!(set.insert(&shape, n), truth.insert(n));
                    set.set_tag(n, x as u8);
                    prop_assert_eq!(set.tag(n), x as u8 & 15);
                    let next = set.bump_tag(n);
                    prop_assert_eq!(next, (x as u8).wrapping_add(1) & 15);
                    prop_assert_eq!(set.tag(n), next);
                } else {
                    prop_assert_eq!(set.remove(n), truth.remove(&n));
                }
                prop_assert_eq!(set.len(), truth.len());
                prop_assert!(set.contains(n) == truth.contains(&n));
            }
            let got: BTreeSet<NodeId> = set.iter().collect();
            prop_assert_eq!(&got, &truth);
            for &n in &truth {
                prop_assert_eq!(set.dense_index(n), shape.index(n));
                if let Some(p) = n.parent() {
                    let mask = set.children_mask(p);
                    for k in 0..4 {
                        prop_assert_eq!(mask >> k & 1 != 0, truth.contains(&p.child(k)));
                    }
                    if let Some(g) = p.parent() {
                        let grand = set.grandchildren_mask(g);
                        for k in 0..4 {
                            let child = g.child(k);
                            prop_assert_eq!(grand >> (4 * k) & 15, set.children_mask(child) as u16);
                        }
                    }
                }
            }
            for n in truth {
                prop_assert!(set.remove(n));
            }
            prop_assert!(set.is_empty());
            // Every page was returned.
            prop_assert_eq!(set.free_pages.len() + 1, set.pages.len().max(1));
            prop_assert_eq!(set.free_supers.len() + 1, set.supers.len().max(1));
        }
    }

    #[test]
    fn the_morton_table_interleaves_the_low_four_bits() {
        for (x, y) in (0..40).flat_map(|x| (0..40).map(move |y| (x, y))) {
            let m = morton8(x, y);
            assert_eq!(m, spread4(x & 15) | spread4(y & 15) << 1);
            assert_eq!((compact4(m), compact4(m >> 1)), (x & 15, y & 15));
        }
    }

    #[test]
    fn a_large_terrain_costs_what_the_set_holds() {
        let shape = TreeShape::new(16385, 16385).unwrap();
        let mut set = NodeSet::default();
        for l in 0..shape.depth() {
            set.insert(
                &shape,
                NodeId {
                    level: l,
                    x: 0,
                    y: 0,
                },
            );
        }
        assert!(set.memory_bytes() < 64 * 1024, "{}", set.memory_bytes());
    }
}
