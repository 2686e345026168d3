//! The order of the translucent pass: back to front.

use glam::Vec3;

/// The translucent draws (those with a box centre in `centres`) back to
/// front: by the distance from `eye` to each rep's box centre, farthest
/// first (blending is not commutative), ties in draw order. Per rep: the
/// triangles of one rep keep their stored order.
pub(crate) fn back_to_front(eye: Vec3, centres: impl Iterator<Item = Option<Vec3>>) -> Vec<usize> {
    let mut far: Vec<(f32, usize)> = centres
        .enumerate()
        .filter_map(|(k, c)| c.map(|c| (c.distance_squared(eye), k)))
        .collect();
    far.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    far.into_iter().map(|(_, k)| k).collect()
}

#[cfg(test)]
mod tests {
    use super::back_to_front;
    use glam::Vec3;

    #[test]
    fn translucent_draws_go_back_to_front_and_opaque_ones_are_left_out() {
        let eye = Vec3::new(0.0, 0.0, 4.0);
        let centres = [
            Some(Vec3::new(0.0, 0.0, 0.5)),  // near glass
            None,                            // opaque
            Some(Vec3::new(0.0, 0.0, -3.0)), // far glass
            Some(Vec3::new(3.5, 0.0, 4.0)),  // beside the eye, as near as the first
            Some(Vec3::new(0.0, 0.0, -1.0)),
        ];
        assert_eq!(back_to_front(eye, centres.into_iter()), [2, 4, 0, 3]);
        // From the other side, the other way round.
        let behind = Vec3::new(0.0, 0.0, -8.0);
        assert_eq!(back_to_front(behind, centres.into_iter()), [3, 0, 4, 2]);
    }
}
