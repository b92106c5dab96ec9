//! Data parallelism: rayon with the `parallel` feature (on by default), otherwise the same
//! calls run in order on the calling thread.
//!
//! The framework's parallel loops are written so their results do not depend on the thread
//! count (fixed chunks, per-chunk buffers summed in a fixed order, see [`crate::partition`]),
//! so turning the feature off changes the speed and not one bit of a result. Off, no thread
//! pool is started and rayon is not compiled: for a consumer that runs its own threads, or a
//! WebAssembly build that has none.
//!
//! Only the calls the framework uses exist sequentially: [`prelude`] brings `par_iter`,
//! `par_iter_mut`, `par_chunks`, `par_chunks_mut` and `par_sort_unstable` on slices, and the
//! iterators they return have rayon's `map`, `zip`, `enumerate`, `filter_map`, `for_each`,
//! `reduce(identity, op)` and the standard iterator's consumers (`collect`, `min`, `max`,
//! `sum`, ...). [`join`] and [`current_num_threads`] complete it.
//!
//! (A small local shim rather than a crate: the sequential stand-ins that exist either
//! re-implement all of rayon's API or pull rayon in anyway; these few calls are all we need.)

#[cfg(feature = "parallel")]
pub use rayon::{current_num_threads, join};

/// The slice and iterator methods of the parallel loops (`use fem_core::par::prelude::*;`).
#[cfg(feature = "parallel")]
pub mod prelude {
    pub use rayon::prelude::*;
}

#[cfg(not(feature = "parallel"))]
pub use sequential::{current_num_threads, join};

/// The slice and iterator methods of the parallel loops (`use fem_core::par::prelude::*;`).
#[cfg(not(feature = "parallel"))]
pub mod prelude {
    pub use super::sequential::{ParallelSlice, ParallelSliceMut};
}

#[cfg(not(feature = "parallel"))]
mod sequential {
    /// 1: without the `parallel` feature every loop runs on the calling thread.
    pub fn current_num_threads() -> usize {
        1
    }

    /// Runs `a`, then `b`, on the calling thread.
    pub fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
    where
        A: FnOnce() -> RA,
        B: FnOnce() -> RB,
    {
        let ra = a();
        (ra, b())
    }

    /// A sequential iterator with rayon's adapters: its inherent `map`, `zip`, `enumerate`,
    /// `filter_map` and `reduce` shadow the standard ones, so code written for rayon compiles
    /// and runs unchanged; the standard iterator's consumers apply through [`Iterator`].
    pub struct Seq<I>(I);

    impl<I: Iterator> Iterator for Seq<I> {
        type Item = I::Item;
        #[inline]
        fn next(&mut self) -> Option<I::Item> {
            self.0.next()
        }
        #[inline]
        fn size_hint(&self) -> (usize, Option<usize>) {
            self.0.size_hint()
        }
    }

    impl<I: Iterator> Seq<I> {
        /// rayon's `map`.
        #[inline]
        pub fn map<B, F: FnMut(I::Item) -> B>(self, f: F) -> Seq<std::iter::Map<I, F>> {
            Seq(self.0.map(f))
        }

        /// rayon's `zip` (with another of these iterators, or anything iterable).
        #[inline]
        pub fn zip<J: IntoIterator>(self, other: J) -> Seq<std::iter::Zip<I, J::IntoIter>> {
            Seq(self.0.zip(other))
        }

        /// rayon's `enumerate`.
        #[inline]
        pub fn enumerate(self) -> Seq<std::iter::Enumerate<I>> {
            Seq(self.0.enumerate())
        }

        /// rayon's `filter_map`.
        #[inline]
        pub fn filter_map<B, F: FnMut(I::Item) -> Option<B>>(
            self,
            f: F,
        ) -> Seq<std::iter::FilterMap<I, F>> {
            Seq(self.0.filter_map(f))
        }

        /// rayon's `reduce`: `op` folds the items into `identity()`, in order.
        #[inline]
        pub fn reduce<ID, OP>(self, identity: ID, op: OP) -> I::Item
        where
            ID: Fn() -> I::Item,
            OP: Fn(I::Item, I::Item) -> I::Item,
        {
            self.0.fold(identity(), op)
        }
    }

    /// `par_iter`, `par_chunks` and friends on shared slices, run in order.
    pub trait ParallelSlice<T> {
        /// The items in order.
        fn par_iter(&self) -> Seq<std::slice::Iter<'_, T>>;
        /// Chunks of `size` items (the last may be shorter), in order.
        fn par_chunks(&self, size: usize) -> Seq<std::slice::Chunks<'_, T>>;
    }

    impl<T> ParallelSlice<T> for [T] {
        #[inline]
        fn par_iter(&self) -> Seq<std::slice::Iter<'_, T>> {
            Seq(self.iter())
        }
        #[inline]
        fn par_chunks(&self, size: usize) -> Seq<std::slice::Chunks<'_, T>> {
            Seq(self.chunks(size))
        }
    }

    /// `par_iter_mut`, `par_chunks_mut` and `par_sort_unstable` on mutable slices, run in
    /// order.
    pub trait ParallelSliceMut<T> {
        /// The items in order.
        fn par_iter_mut(&mut self) -> Seq<std::slice::IterMut<'_, T>>;
        /// Chunks of `size` items (the last may be shorter), in order.
        fn par_chunks_mut(&mut self, size: usize) -> Seq<std::slice::ChunksMut<'_, T>>;
        /// [`slice::sort_unstable`].
        fn par_sort_unstable(&mut self)
        where
            T: Ord;
    }

    impl<T> ParallelSliceMut<T> for [T] {
        #[inline]
        fn par_iter_mut(&mut self) -> Seq<std::slice::IterMut<'_, T>> {
            Seq(self.iter_mut())
        }
        #[inline]
        fn par_chunks_mut(&mut self, size: usize) -> Seq<std::slice::ChunksMut<'_, T>> {
            Seq(self.chunks_mut(size))
        }
        #[inline]
        fn par_sort_unstable(&mut self)
        where
            T: Ord,
        {
            self.sort_unstable()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::prelude::*;

    #[test]
    fn the_loops_give_the_serial_results() {
        let a: Vec<u64> = (0..1000).collect();
        let mut b = vec![0u64; 1000];
        b.par_chunks_mut(64)
            .zip(a.par_chunks(64))
            .enumerate()
            .for_each(|(c, (out, inp))| {
                for (o, i) in out.iter_mut().zip(inp) {
                    *o = i * 2 + c as u64;
                }
            });
        let want: Vec<u64> = (0..1000u64).map(|i| i * 2 + i / 64).collect();
        assert_eq!(b, want);
        let all_even = a
            .par_chunks(100)
            .map(|c| c.iter().all(|v| v % 2 == 0))
            .reduce(|| true, |x, y| x && y);
        assert!(!all_even);
        let odd: Vec<u64> = a
            .par_iter()
            .filter_map(|&v| (v % 2 == 1).then_some(v))
            .collect();
        assert_eq!(odd.len(), 500);
        let mut s = vec![3, 1, 2];
        s.par_sort_unstable();
        assert_eq!(s, [1, 2, 3]);
        assert_eq!(super::join(|| 1, || 2), (1, 2));
        assert!(super::current_num_threads() >= 1);
    }
}
