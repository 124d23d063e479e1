//! The figures a shop reads off a stability diagram: the deepest stable cut over the diagram's
//! speeds (the top of the highest lobe) and its speed, and the depth stable at every speed.

use spindlelab_domain::value::Lobes;

/// The best cut of a diagram.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BestCut {
    /// The largest limiting depth over the speeds (m), `+∞` where no lobe limits some speed.
    pub depth_m: f64,
    /// The speed it is reached at (rpm): the first of equal maxima.
    pub speed_rpm: f64,
    /// The chatter frequency of the lobe that limits it there (Hz; NaN where none does).
    pub chatter_hz: f64,
    /// The smallest limiting depth over the speeds (m): stable at any of them.
    pub stable_everywhere_m: f64,
}

/// The best cut of `lobes`; `None` for a diagram of no speeds or no valid depth.
pub fn best_cut(lobes: &Lobes) -> Option<BestCut> {
    let valid = |d: f64| !d.is_nan() && d >= 0.0;
    let mut best: Option<usize> = None;
    let mut least = f64::INFINITY;
    for (i, &d) in lobes.depth_limit.iter().enumerate().filter(|(_, d)| valid(**d)) {
        if best.is_none_or(|b| d > lobes.depth_limit[b]) {
            best = Some(i);
        }
        least = least.min(d);
    }
    let b = best?;
    Some(BestCut {
        depth_m: lobes.depth_limit[b],
        speed_rpm: lobes.speed.get(b).map_or(f64::NAN, |s| s.rpm_as_written()),
        chatter_hz: lobes.chatter_hz.get(b).copied().unwrap_or(f64::NAN),
        stable_everywhere_m: least,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diagram of two lobes, written by hand: the best cut is the top of the higher one,
    /// and the depth stable everywhere the lowest minimum; invalid depths are passed over.
    #[test]
    fn the_best_cut_is_the_top_of_the_highest_lobe() {
        let lobes = Lobes {
            speed: vec![1000.0, 2000.0, 3000.0, 4000.0, 5000.0, 6000.0]
                .into_iter()
                .map(spindlelab_domain::Speed::from_rpm)
                .collect(),
            depth_limit: vec![1e-3, 4e-3, 0.5e-3, f64::NAN, 6e-3, 2e-3],
            chatter_hz: vec![800.0, 810.0, 790.0, f64::NAN, 820.0, 805.0],
        };
        let b = best_cut(&lobes).unwrap();
        assert_eq!((b.depth_m, b.speed_rpm, b.chatter_hz, b.stable_everywhere_m), (6e-3, 5000.0, 820.0, 0.5e-3));
        let none = Lobes {
            speed: vec![1.0].into_iter().map(spindlelab_domain::Speed::from_rpm).collect(),
            depth_limit: vec![f64::NAN],
            chatter_hz: vec![f64::NAN],
        };
        assert_eq!(best_cut(&none), None);
    }
}
