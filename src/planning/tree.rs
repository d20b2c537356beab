//! RRT search trees (LaValle 1998): states in one flat `Vec<f64>` with parent indices, and an
//! exact nearest-neighbour query by linear scan in the space's weighted metric. Cache-friendly
//! and allocation-free per query; adequate for the few thousand states of a typical query.

/// Parent index of a root state.
pub const NO_PARENT: u32 = u32::MAX;

/// A tree (or forest: several roots are allowed) of states of one space.
#[derive(Debug, Clone)]
pub struct Tree {
    dim: usize,
    weights: Vec<f64>,
    states: Vec<f64>,
    parents: Vec<u32>,
}

impl Tree {
    /// An empty tree of `weights.len()`-dimensional states measured with these weights.
    pub fn new(weights: &[f64]) -> Tree {
        Tree {
            dim: weights.len(),
            weights: weights.to_vec(),
            states: Vec::with_capacity(weights.len() * 1024),
            parents: Vec::with_capacity(1024),
        }
    }

    /// Removes every state (keeps the memory).
    pub fn clear(&mut self) {
        self.states.clear();
        self.parents.clear();
    }

    #[inline]
    pub fn len(&self) -> usize {
        self.parents.len()
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.parents.is_empty()
    }

    /// Adds a state with `parent` (or [`NO_PARENT`] for a root) and returns its index.
    #[inline]
    pub fn add(&mut self, q: &[f64], parent: u32) -> u32 {
        debug_assert_eq!(q.len(), self.dim);
        debug_assert!(parent == NO_PARENT || (parent as usize) < self.len());
        self.states.extend_from_slice(q);
        self.parents.push(parent);
        (self.parents.len() - 1) as u32
    }

    #[inline]
    pub fn state(&self, i: u32) -> &[f64] {
        let s = i as usize * self.dim;
        &self.states[s..s + self.dim]
    }

    #[inline]
    pub fn parent(&self, i: u32) -> Option<u32> {
        let p = self.parents[i as usize];
        (p != NO_PARENT).then_some(p)
    }

    /// The root reached by following parents from `i`.
    pub fn root_of(&self, mut i: u32) -> u32 {
        while let Some(p) = self.parent(i) {
            i = p;
        }
        i
    }

    /// Index and squared weighted distance of the state nearest to `q` (`None` when empty).
    #[inline]
    pub fn nearest(&self, q: &[f64]) -> Option<(u32, f64)> {
        let mut best = f64::INFINITY;
        let mut best_i = None;
        for (i, s) in self.states.chunks_exact(self.dim).enumerate() {
            let mut d = 0.0;
            for k in 0..self.dim {
                let e = s[k] - q[k];
                d += self.weights[k] * e * e;
            }
            if d < best {
                best = d;
                best_i = Some(i as u32);
            }
        }
        best_i.map(|i| (i, best))
    }

    /// Indices from the root down to `i` (into `out`, cleared first).
    pub fn path_from_root(&self, i: u32, out: &mut Vec<u32>) {
        out.clear();
        let mut k = i;
        out.push(k);
        while let Some(p) = self.parent(k) {
            out.push(p);
            k = p;
        }
        out.reverse();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_and_paths() {
        let mut t = Tree::new(&[1.0, 4.0]);
        assert!(t.nearest(&[0.0, 0.0]).is_none());
        let r = t.add(&[0.0, 0.0], NO_PARENT);
        let a = t.add(&[1.0, 0.0], r);
        let b = t.add(&[0.0, 0.6], a);
        // Weighted: b is 4·0.36 = 1.44 away from the origin, a only 1.
        assert_eq!(t.nearest(&[0.0, 0.55]).map(|x| x.0), Some(b));
        assert_eq!(t.nearest(&[0.6, 0.0]).map(|x| x.0), Some(a));
        let mut p = Vec::new();
        t.path_from_root(b, &mut p);
        assert_eq!(p, vec![r, a, b]);
        assert_eq!(t.root_of(b), r);
        assert_eq!(t.parent(r), None);
    }
}
