//! A distance ordered totally (`f64::total_cmp`), for priority queues of Dijkstra-style
//! walks over a mesh's edges.

/// A distance (mm) with a total order: usable in a `BinaryHeap`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrderedMm(pub f64);

impl Eq for OrderedMm {}

impl PartialOrd for OrderedMm {
    fn partial_cmp(&self, other: &OrderedMm) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OrderedMm {
    fn cmp(&self, other: &OrderedMm) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;

    #[test]
    fn a_min_heap_pops_the_shortest_first_and_nan_last() {
        let mut heap: BinaryHeap<Reverse<OrderedMm>> = [3.0, f64::NAN, 0.5, 2.0]
            .map(|d| Reverse(OrderedMm(d)))
            .into();
        let order: Vec<f64> = std::iter::from_fn(|| heap.pop().map(|Reverse(d)| d.0)).collect();
        assert_eq!(&order[..3], &[0.5, 2.0, 3.0]);
        assert!(order[3].is_nan());
    }
}
