//! The angular sweep: exact visibility from one point over a short candidate list.

use super::*;

/// How many sweeps sort with [`Sweeper::bucket_sort`] straight away after
/// the insertion sort from the previous order gave up (the next points are
/// neighbours, where it would most likely give up again).
const BUCKET_SWEEPS: u32 = 64;

impl Sweeper {
    /// The visible spans seen from `at`, among `candidates` (indices into
    /// `edges`) that belong to its free-space component. Spans are appended
    /// to `out` in increasing pseudo-angle.
    pub fn sweep(
        &mut self,
        edges: &[Edge],
        candidates: &[u32],
        at: Viewpoint,
        out: &mut Vec<Span>,
    ) {
        self.sweep_wanted(edges, candidates, at, None, out);
    }

    /// [`Sweeper::sweep`], returning only the spans `wanted`; returns how
    /// many spans of edges with light it left out.
    pub fn sweep_wanted(
        &mut self,
        edges: &[Edge],
        candidates: &[u32],
        at: Viewpoint,
        wanted: Option<Wanted>,
        out: &mut Vec<Span>,
    ) -> u64 {
        let q = Query::new(at);
        let p = at.p;
        self.pieces.clear();
        self.events.clear();
        // The last piece is its edge's only one (not a silhouette).
        let mut single = false;
        for (j, &ei) in candidates.iter().enumerate() {
            let from = self.pieces.len();
            q.pieces(edges, ei, &mut self.pieces);
            let Some(w) = wanted else { continue };
            if self.pieces.len() == from {
                continue;
            }
            Self::mark(&mut self.pieces[from..], w.at(edges, ei, Some(j), &q));
            if self.pieces.len() == from + 1 && single && self.take_silhouette(edges, &q) {
                single = false;
                continue;
            }
            single = self.pieces.len() == from + 1;
        }
        if self.pieces.is_empty() {
            return 0;
        }
        let mut left_out = 0;
        self.shape.clear();
        self.first_event.clear();
        for (id, pc) in self.pieces.iter().enumerate() {
            self.first_event.push(self.events.len() as u32);
            if pc.face {
                continue;
            }
            let part = u32::from(id > 0 && self.pieces[id - 1].edge == pc.edge);
            let base = pc.edge * 4 + part * 2;
            // A silhouette's end is its second edge's (never split).
            let end = if pc.silhouette { pc.edge_b * 4 } else { base };
            self.events.push(Event::new(pc.ka, base + 1, 2 * id as u32));
            self.events.push(Event::new(pc.kb, end, 2 * id as u32 + 1));
            self.shape.push(base | (u32::from(pc.silhouette) << 31));
        }
        let same = self.shape == self.prev_shape;
        std::mem::swap(&mut self.shape, &mut self.prev_shape);
        self.sort_events(edges.len(), same, q.kmax());
        self.active.clear();
        let n = self.events.len();
        let mut i = 0;
        const NONE: u32 = u32::MAX;
        // The span under construction: its piece (`NONE` if none), start
        // key and start vertex (three locals: as one `Option` of a tuple,
        // its copy on every change stalled on a store).
        let (mut open, mut open_k, mut open_v) = (NONE, 0.0, [0.0; 2]);
        // Position of each piece in `active` (for O(1) removal).
        self.at.clear();
        self.at.resize(self.pieces.len(), u32::MAX);
        // Nearest piece of the previous interval.
        let mut current: Option<u32> = None;
        // While a silhouette is nearest from before its corner on: that
        // its second piece is still to be counted where it becomes
        // nearest, past the corner (see below).
        let mut before_corner = false;
        while i < n {
            let key = self.events[i].key();
            let vertex = {
                let ev = self.events[i];
                let pc = &self.pieces[ev.piece() as usize];
                if ev.insert() { pc.va } else { pc.vb }
            };
            self.fresh.clear();
            let mut lost_nearest = false;
            while i < n && self.events[i].key() == key {
                let ev = self.events[i];
                let piece = ev.piece();
                if ev.insert() {
                    self.at[piece as usize] = self.active.len() as u32;
                    self.active.push(piece);
                    self.fresh.push(piece);
                } else {
                    let pos = self.at[piece as usize];
                    if pos != u32::MAX {
                        let pos = pos as usize;
                        self.active.swap_remove(pos);
                        if let Some(&moved) = self.active.get(pos) {
                            self.at[moved as usize] = pos as u32;
                        }
                        self.at[piece as usize] = u32::MAX;
                        lost_nearest |= current == Some(piece);
                    }
                }
                i += 1;
            }
            // Nearest active piece on the interval (key, next key). Edges do
            // not cross, so among pieces active on both sides of an event
            // the nearer stays nearer: unless the nearest piece just ended,
            // only the pieces that just started can take its place.
            let nearest = if i >= n || self.active.is_empty() {
                None
            } else if !lost_nearest && self.fresh.is_empty() && current.is_some() {
                // Only pieces behind the nearest ended: it stays nearest.
                current
            } else {
                let (du, dv) = diamond_dir(0.5 * (key + self.events[i].key()));
                // Compared along one ray, so any positive multiple of the
                // ray parameter will do: `t |du| |dv|` needs no division.
                // An axis-parallel ray keeps the plain parameter.
                let axis = du == 0.0 || dv == 0.0;
                let (su, sv) = if axis {
                    (1.0 / du.abs(), 1.0 / dv.abs())
                } else {
                    (dv.abs(), du.abs())
                };
                let mut best = u32::MAX;
                let mut best_t = f64::INFINITY;
                let scale = if axis { 1.0 } else { du.abs() * dv.abs() };
                let mut consider = |a: u32| {
                    let pc = &self.pieces[a as usize];
                    let t = if pc.silhouette {
                        // `t = scale / den`, `den > 0` for a ray that
                        // hits the segment in front: divided only where
                        // it may be nearer.
                        let den = pc.sa * du + pc.sb * dv;
                        let bound = best_t * den;
                        if bound.is_nan() || scale > bound {
                            return;
                        }
                        scale / den
                    } else {
                        pc.t_scaled(su, sv)
                    };
                    if t < best_t || (t == best_t && a < best) {
                        best_t = t;
                        best = a;
                    }
                };
                match current {
                    Some(c) if !lost_nearest => {
                        consider(c);
                        for &a in &self.fresh {
                            consider(a);
                        }
                    }
                    _ => {
                        for &a in &self.active {
                            consider(a);
                        }
                    }
                }
                Some(best)
            };
            // The nearest piece's span, unless it is not wanted (then it
            // only hides what is behind it).
            let shown = match nearest {
                Some(pc) if !self.pieces[pc as usize].lit => {
                    let piece = &self.pieces[pc as usize];
                    // A silhouette counts as its two pieces would: each
                    // where it becomes nearest, the second past the
                    // corner (`c`), on the interval to the next event.
                    let corner = piece.c;
                    if current != nearest {
                        before_corner = piece.silhouette && key < corner;
                        let dim = if piece.silhouette && !before_corner {
                            piece.dim_b
                        } else {
                            piece.dim
                        };
                        left_out += u64::from(dim);
                    }
                    if before_corner && self.events[i].key() > corner {
                        before_corner = false;
                        left_out += u64::from(piece.dim_b);
                    }
                    None
                }
                _ => nearest,
            };
            current = nearest;
            let shown = shown.unwrap_or(NONE);
            if open != shown {
                if open != NONE {
                    self.emit_shown(edges, p, open, (open_k, open_v), (key, vertex), out);
                }
                (open, open_k, open_v) = (shown, key, vertex);
            }
        }
        debug_assert!(open == NONE, "the last event closes every span");
        left_out
    }

    /// Takes the last two `pieces`, each its edge's only one, as one
    /// [`silhouette`] if both are wanted or neither is, and they meet at a
    /// convex corner; returns whether it did. A field of one-pixel pillars,
    /// seen from a pixel, is two unwanted pieces per pillar, most of them
    /// only hiding what is behind them; a field of lamps, two wanted
    /// pieces per lamp. The sweep then sorts half as many events. The
    /// candidates list a pillar's edges together (their loop's), so its
    /// two pieces come one after the other. An unwanted silhouette takes
    /// their place; a wanted one follows them, in order, marked
    /// [`Piece::face`], and its spans are cut into theirs
    /// ([`Sweeper::emit_shown`]).
    #[inline]
    fn take_silhouette(&mut self, edges: &[Edge], q: &Query) -> bool {
        let n = self.pieces.len();
        let (a, b) = (&self.pieces[n - 2], &self.pieces[n - 1]);
        if a.lit != b.lit || self.no_silhouettes {
            return false;
        }
        let Some((mut m, swapped)) = silhouette(edges, q, a, b) else {
            return false;
        };
        self.silhouettes += 1;
        if !a.lit {
            self.pieces[n - 2] = m;
            self.pieces.pop();
            return true;
        }
        if swapped {
            self.pieces.swap(n - 2, n - 1);
        }
        self.pieces[n - 2].face = true;
        self.pieces[n - 1].face = true;
        m.lit = true;
        self.pieces.push(m);
        true
    }

    /// Emits the span of piece `pc` from `from` to `to`; a silhouette's as
    /// its two faces' (the two pieces before it, in order), cut at its
    /// corner (as a walk reads a silhouette's spans off its coverage).
    #[inline]
    fn emit_shown(
        &self,
        edges: &[Edge],
        p: [f64; 2],
        pc: u32,
        from: (f64, [f64; 2]),
        to: (f64, [f64; 2]),
        out: &mut Vec<Span>,
    ) {
        let piece = &self.pieces[pc as usize];
        if !piece.silhouette {
            self.emit(edges, p, pc, from, to, out);
            return;
        }
        let (corner, at) = (piece.c, self.pieces[pc as usize - 2].vb);
        if from.0 < corner {
            let end = if to.0 <= corner { to } else { (corner, at) };
            self.emit(edges, p, pc - 2, from, end, out);
        }
        if to.0 > corner {
            let start = if from.0 >= corner { from } else { (corner, at) };
            self.emit(edges, p, pc - 1, start, to, out);
        }
    }

    /// Marks the `pieces` of one edge as wanted or not (`(lit, dim)`, see
    /// [`Piece`]).
    #[inline]
    pub(super) fn mark(pieces: &mut [Piece], (lit, dim): (bool, bool)) {
        for pc in pieces {
            pc.lit = lit;
            pc.dim = dim;
        }
    }

    /// Sorts `events` by key, ties by id: a total order, so the result does
    /// not depend on the order they came in or on how they are sorted.
    ///
    /// Neighbouring points see nearly the same angular order, so the
    /// events are first laid out in the previous sweep's order, which an
    /// insertion sort then only has to patch up: linear in the number of
    /// events plus the number of pairs out of order. Where that number is
    /// large (hundreds of edges at every distance, as in a field of
    /// pillars: a step of one pixel moves every near event past many
    /// others), the insertion sort gives up past a budget of moves and a
    /// [bucket sort](Sweeper::bucket_sort) does the job, as it then does
    /// for the next [`BUCKET_SWEEPS`] sweeps without trying.
    ///
    /// `same`: the pieces are those of the previous sweep, in the same order
    /// (neighbours usually see the same edges, split the same way), so an
    /// event's index is that of its counterpart in the previous sweep.
    fn sort_events(&mut self, edges: usize, same: bool, kmax: f64) {
        if self.bucket_sweeps > 0 {
            self.bucket_sweeps -= 1;
            self.bucket_sort(kmax);
        } else {
            let keys = &mut self.sorted;
            keys.clear();
            if same && self.codes.len() == self.events.len() {
                keys.extend(self.codes.iter().map(|&c| self.events[c as usize]));
            } else {
                self.lay_out_by_id(edges);
            }
            let budget = self.sorted.len() + 64;
            if !insertion_sort(&mut self.sorted, budget) {
                self.bucket_sweeps = BUCKET_SWEEPS;
                self.bucket_sort(kmax);
            }
        }
        let keys = &self.sorted;
        self.order.clear();
        self.order.extend(keys.iter().map(|k| k.id()));
        self.codes.clear();
        self.codes.extend(
            keys.iter()
                .map(|k| self.first_event[k.piece() as usize] + (k.code() & 1)),
        );
        std::mem::swap(&mut self.events, &mut self.sorted);
    }

    /// Sorts `events` into `sorted` in [`Sweeper::sort_events`]'s order,
    /// whatever order they come in: a counting sort into one bucket per
    /// event over `[0, kmax]`, then an insertion sort over the whole. The
    /// bucket is a non-decreasing function of the key in
    /// [`f64::total_cmp`]'s order, so the insertion sort only reorders
    /// events within a bucket (it would sort correctly whatever the
    /// buckets; they make it linear).
    fn bucket_sort(&mut self, kmax: f64) {
        let n = self.events.len();
        let nb = n.max(1);
        let scale = nb as f64 / kmax;
        let bucket = |ev: &Event| -> usize {
            let k = ev.key();
            if k.is_nan() {
                if k.is_sign_negative() { 0 } else { nb - 1 }
            } else {
                // Negative keys (and -0) go to the first bucket, keys past
                // `kmax` (and infinity) to the last.
                ((k.max(0.0) * scale) as usize).min(nb - 1)
            }
        };
        let start = &mut self.bucket_start;
        start.clear();
        start.resize(nb + 1, 0);
        self.bucket_of.clear();
        for ev in &self.events {
            let b = bucket(ev);
            self.bucket_of.push(b as u32);
            start[b + 1] += 1;
        }
        // Running sums in a register: `start[b + 1] += start[b]` would
        // wait on the store of the sum before.
        let mut sum = 0;
        for s in start.iter_mut() {
            sum += *s;
            *s = sum;
        }
        let keys = &mut self.sorted;
        keys.clear();
        keys.resize(n, Event(0));
        for (ev, &b) in self.events.iter().zip(&self.bucket_of) {
            let at = &mut start[b as usize];
            keys[*at as usize] = *ev;
            *at += 1;
        }
        // Out of order now only within a bucket (a few events each): one
        // insertion sort over the whole finishes it.
        insertion_sort(keys, usize::MAX);
    }

    /// Lays `events` out in the previous sweep's order by id (the events
    /// of pieces that are new come last), into `sorted`.
    fn lay_out_by_id(&mut self, edges: usize) {
        self.slot.clear(edges * 4);
        for (i, ev) in self.events.iter().enumerate() {
            self.slot.set(ev.id() as usize, i as u32);
        }
        // Laid out in the previous order first, then the new ones; ties
        // between equal keys and ids (a repeated candidate) by `code`.
        let keys = &mut self.sorted;
        for &id in &self.order {
            if let Some(i) = self.slot.get(id as usize) {
                keys.push(self.events[i as usize]);
                self.slot.unset(id as usize);
            }
        }
        for ev in &self.events {
            if self.slot.get(ev.id() as usize).is_some() {
                keys.push(*ev);
            }
        }
        if keys.len() != self.events.len() {
            // A repeated candidate gave two events one id: start afresh.
            keys.clear();
            keys.extend_from_slice(&self.events);
        }
    }
}

/// Pieces `a` and `b` as one silhouette, if they meet end to end (the
/// same vertex at the same pseudo-angle) at a convex corner of solid, and
/// one of their edges is at most one pixel long or both are sides of one
/// rectangle ([`Edge::rectangle`]); and whether `b` comes first (at `ka`).
/// Nothing lies between the two pieces and the straight segment across
/// their far ends: that triangle is at most a pixel deep behind the longer
/// edge, and every edge has solid for a pixel behind it (or it lies inside
/// the rectangle). So the segment hides from the query point exactly what
/// the two pieces hide.
///
/// Inlined into its callers: returned through memory, the piece was
/// written in parts and read back whole, a stall on every silhouette.
#[inline(always)]
pub(super) fn silhouette(edges: &[Edge], q: &Query, a: &Piece, b: &Piece) -> Option<(Piece, bool)> {
    if a.edge == b.edge || a.silhouette || b.silhouette {
        return None;
    }
    let (f, s) = if a.kb == b.ka && a.vb == b.va {
        (a, b)
    } else if b.kb == a.ka && b.vb == a.va {
        (b, a)
    } else {
        return None;
    };
    let (ef, es) = (&edges[f.edge as usize], &edges[s.edge as usize]);
    let rectangle = ef.rectangle && es.rectangle && ef.loop_id == es.loop_id;
    if ef.len() > 1.0 && es.len() > 1.0 && !rectangle {
        return None;
    }
    // Convex: the second piece runs from the corner to the solid side of
    // the first's edge.
    let n = ef.normal.vec();
    let (corner, far) = (f.vb, s.vb);
    if (far[0] - corner[0]) * n[0] as f64 + (far[1] - corner[1]) * n[1] as f64 >= 0.0 {
        return None;
    }
    // The line through the far ends, `nu u + nv v = c`, scaled to `c = 1`
    // (the query point is not on it: the ends are at different angles).
    let ((au, av), (cu, cv)) = (q.local(f.va), q.local(far));
    let (nu, nv) = (cv - av, au - cu);
    let c = nu * au + nv * av;
    if c == 0.0 || !c.is_finite() {
        return None;
    }
    let piece = Piece {
        edge: f.edge,
        edge_b: s.edge,
        u_const: false,
        silhouette: true,
        c: f.kb,
        ka: f.ka,
        kb: s.kb,
        sa: nu / c,
        sb: nv / c,
        va: f.va,
        vb: far,
        lit: false,
        dim: f.dim,
        dim_b: s.dim,
        face: false,
    };
    Some((piece, std::ptr::eq(f, b)))
}

/// Sorts `keys` by insertion: linear in their number plus the number of
/// pairs out of order. Gives up, leaving them partly sorted, once that
/// number passes `budget` moves; returns whether they are sorted.
fn insertion_sort(keys: &mut [Event], budget: usize) -> bool {
    let mut moves = 0;
    for i in 1..keys.len() {
        if moves > budget {
            return false;
        }
        let x = keys[i];
        let mut j = i;
        while j > 0 && x < keys[j - 1] {
            keys[j] = keys[j - 1];
            j -= 1;
        }
        moves += i - j;
        keys[j] = x;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Keys as a sweep makes them (pseudo-angles in `[0, kmax]`), with the
    /// odd ones a degenerate query gives: equal keys, -0, NaN of both signs,
    /// infinity and keys past `kmax`.
    fn key() -> impl Strategy<Value = f64> {
        prop_oneof![
            8 => 0.0..4.0f64,
            2 => (0u32..8).prop_map(|i| i as f64 * 0.5),
            1 => Just(-0.0),
            1 => Just(f64::NAN),
            1 => Just(-f64::NAN),
            1 => Just(f64::INFINITY),
            1 => 4.0..9.0f64,
        ]
    }

    proptest! {
        /// The bucket sort gives the order of a plain sort of the events
        /// (key in `total_cmp`'s order, then id, then code), for full and
        /// half views.
        #[test]
        fn bucket_sort_agrees_with_a_plain_sort(
            keys in prop::collection::vec((key(), 0u32..64, 0u32..64), 0..300),
            half in any::<bool>(),
        ) {
            let mut s = Sweeper::new();
            s.events = keys.iter().map(|&(k, id, code)| Event::new(k, id, code)).collect();
            let mut want = s.events.clone();
            want.sort_unstable();
            s.bucket_sort(if half { 2.0 } else { 4.0 });
            prop_assert_eq!(&s.sorted, &want);
        }
    }
}
