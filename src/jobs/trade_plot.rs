//! `compare.svg`: the speed/accuracy trade of a comparison's variants and its
//! Pareto front.
//!
//! Each variant is a point: median frame time per light (x, log scale) against
//! mismatched pixels off a reference shadow boundary (y, on a `log10(1 + m)`
//! scale so that the exact variants, `m = 0`, sit on the bottom line and
//! mismatches of 1 to 10⁶ stay readable). A variant is on the *Pareto front*
//! when no other variant is at least as fast and at least as close to the
//! reference, and strictly better in one of the two: those are the only
//! settings worth choosing, and the front joins them with a staircase.
//!
//! Labels are placed greedily, fastest point first, each at the first of
//! rings of candidate offsets around its point whose box
//! overlaps no label placed before and no other point; a label moved away
//! from its point gets a thin leader line.

use std::path::Path;

/// One variant on the plot.
#[derive(Clone, Debug)]
pub(crate) struct TradePoint {
    /// Variant name (the label).
    pub name: String,
    /// Median frame time per light (ms).
    pub ms: f64,
    /// Mismatched pixels off a reference boundary.
    pub mismatch: u64,
    /// On the Pareto front ([`pareto_front`], computed once by the caller).
    pub front: bool,
}

/// Per point, whether it is on the Pareto front of (time, mismatch), both
/// minimized: no other point is at least as good in both and better in one.
/// Points with a non-finite time are never on the front and never dominate.
pub(crate) fn pareto_front(points: &[(f64, u64)]) -> Vec<bool> {
    let dominates = |a: (f64, u64), b: (f64, u64)| {
        a.0.is_finite() && a.0 <= b.0 && a.1 <= b.1 && (a.0 < b.0 || a.1 < b.1)
    };
    points
        .iter()
        .map(|&p| p.0.is_finite() && !points.iter().any(|&q| dominates(q, p)))
        .collect()
}

/// An axis-aligned box in pixels: `(x0, y0, x1, y1)`, exclusive ends.
type Rect = (i32, i32, i32, i32);

fn overlaps(a: Rect, b: Rect) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// Top-left corners for labels of `sizes` (width, height) at `anchors`, in
/// order: each at the first candidate offset (nearest first) whose box lies
/// inside `area` and overlaps no earlier label and no anchor's marker (a
/// square of `2 * marker` pixels); if none is free, at the nearest one
/// inside `area`.
pub(crate) fn place_labels(
    anchors: &[(i32, i32)],
    sizes: &[(i32, i32)],
    area: Rect,
    marker: i32,
) -> Vec<(i32, i32)> {
    let markers: Vec<Rect> = anchors
        .iter()
        .map(|&(x, y)| (x - marker, y - marker, x + marker + 1, y + marker + 1))
        .collect();
    let mut placed: Vec<Rect> = Vec::with_capacity(anchors.len());
    let mut corners = Vec::with_capacity(anchors.len());
    for (&(x, y), &(w, h)) in anchors.iter().zip(sizes) {
        // Rings of candidates: right, left, above, below, then diagonals,
        // each ring one label height farther out.
        let gap = marker + 3;
        let mut candidates = Vec::new();
        for ring in 0..12 {
            let d = ring * h;
            candidates.extend([
                (x + gap, y - h / 2 - d),
                (x + gap, y - h / 2 + d),
                (x - gap - w, y - h / 2 - d),
                (x - gap - w, y - h / 2 + d),
                (x - w / 2, y - gap - h - d),
                (x - w / 2, y + gap + d),
            ]);
        }
        let rect = |(cx, cy): (i32, i32)| (cx, cy, cx + w, cy + h);
        let inside = |r: Rect| r.0 >= area.0 && r.1 >= area.1 && r.2 <= area.2 && r.3 <= area.3;
        let free = |r: Rect| {
            inside(r)
                && !placed.iter().any(|&p| overlaps(p, r))
                && !markers.iter().any(|&m| overlaps(m, r))
        };
        let corner = candidates
            .iter()
            .copied()
            .find(|&c| free(rect(c)))
            .or_else(|| candidates.iter().copied().find(|&c| inside(rect(c))))
            .unwrap_or(candidates[0]);
        placed.push(rect(corner));
        corners.push(corner);
    }
    corners
}

/// Approximate width in pixels of `text` in a sans-serif font of `size` px.
fn text_width(text: &str, size: i32) -> i32 {
    (text.chars().count() as f64 * size as f64 * 0.56).ceil() as i32 + 2
}

/// `log10(1 + m)`: the y coordinate of a mismatch count.
fn y_of(m: f64) -> f64 {
    (1.0 + m).log10()
}

/// Writes the plot of `points` (see the module docs) to `path` as SVG.
pub(crate) fn plot(
    points: &[TradePoint],
    path: &Path,
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    const FONT: i32 = 13;
    let drawn: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].ms.is_finite() && points[i].ms >= 0.0)
        .collect();
    let ms = |i: usize| points[i].ms.max(1e-3);
    let x_lo = drawn.iter().map(|&i| ms(i)).fold(f64::INFINITY, f64::min);
    let x_hi = drawn.iter().map(|&i| ms(i)).fold(0.0, f64::max);
    let (x_lo, x_hi) = if x_lo.is_finite() {
        (x_lo / 1.25, x_hi * 1.6)
    } else {
        (0.1, 10.0)
    };
    let m_max = drawn.iter().map(|&i| points[i].mismatch).max().unwrap_or(0);
    let y_hi = y_of(m_max as f64).max(1.0) * 1.15 + 0.2;

    let root = SVGBackend::new(path, (960, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "shadowcull compare: time against mismatch (red: Pareto front)",
            ("sans-serif", 20),
        )
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d((x_lo..x_hi).log_scale(), -0.15 * y_hi..y_hi)?;
    // Mismatch ticks at 0 and the powers of ten, in the log10(1 + m) space.
    let ticks: Vec<u64> = std::iter::once(0)
        .chain((0..10).map(|k| 10u64.pow(k)))
        .filter(|&m| y_of(m as f64) <= y_hi)
        .collect();
    chart
        .configure_mesh()
        .x_desc("median frame time per light (ms, log scale)")
        .y_desc("mismatched pixels off a shadow boundary")
        .y_labels(0)
        .disable_y_mesh()
        .draw()?;
    for &m in &ticks {
        let y = y_of(m as f64);
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(x_lo, y), (x_hi, y)],
            RGBColor(225, 225, 225),
        )))?;
        let (px, py) = chart.backend_coord(&(x_lo, y));
        let text = if m >= 1000 {
            format!("{}k", m / 1000)
        } else {
            m.to_string()
        };
        root.draw(&Text::new(
            text.clone(),
            (px - 8 - text_width(&text, FONT), py - FONT / 2),
            ("sans-serif", FONT),
        ))?;
    }

    // The front: a staircase through its points, fastest first.
    let mut on_front: Vec<usize> = drawn.iter().copied().filter(|&i| points[i].front).collect();
    on_front.sort_by(|&a, &b| ms(a).total_cmp(&ms(b)));
    let mut stairs = Vec::new();
    for (k, &i) in on_front.iter().enumerate() {
        let y = y_of(points[i].mismatch as f64);
        if k > 0 {
            let prev = y_of(points[on_front[k - 1]].mismatch as f64);
            stairs.push((ms(i), prev));
        }
        stairs.push((ms(i), y));
    }
    if let Some(&last) = on_front.last() {
        stairs.push((x_hi, y_of(points[last].mismatch as f64)));
    }
    chart.draw_series(std::iter::once(PathElement::new(
        stairs,
        RED.stroke_width(2),
    )))?;

    // Points, then their labels, fastest first.
    let mut order = drawn.clone();
    order.sort_by(|&a, &b| ms(a).total_cmp(&ms(b)));
    let anchors: Vec<(i32, i32)> = order
        .iter()
        .map(|&i| chart.backend_coord(&(ms(i), y_of(points[i].mismatch as f64))))
        .collect();
    for (&i, &(x, y)) in order.iter().zip(&anchors) {
        let color = if points[i].front {
            RED
        } else {
            RGBColor(90, 90, 90)
        };
        root.draw(&Circle::new((x, y), 4, color.filled()))?;
    }
    let (px, py) = chart.plotting_area().get_pixel_range();
    let area = (px.start, py.start, px.end, py.end);
    let sizes: Vec<(i32, i32)> = order
        .iter()
        .map(|&i| (text_width(&points[i].name, FONT), FONT + 3))
        .collect();
    let corners = place_labels(&anchors, &sizes, area, 5);
    for (k, &i) in order.iter().enumerate() {
        let (ax, ay) = anchors[k];
        let (cx, cy) = corners[k];
        let (w, h) = sizes[k];
        let (nx, ny) = (ax.clamp(cx, cx + w), ay.clamp(cy, cy + h));
        if (nx - ax).abs() + (ny - ay).abs() > 12 {
            root.draw(&PathElement::new(
                vec![(ax, ay), (nx, ny)],
                RGBColor(170, 170, 170),
            ))?;
        }
        let color = if points[i].front { RED } else { BLACK };
        root.draw(&Text::new(
            points[i].name.clone(),
            (cx, cy + 1),
            ("sans-serif", FONT).into_font().color(&color),
        ))?;
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_front_keeps_what_nothing_beats() {
        let pts = [
            (10.0, 0), // exact, slow: on the front
            (5.0, 0),  // exact, faster: on the front, beats the first
            (4.0, 30), // faster, inexact: on the front
            (6.0, 30), // beaten by (5, 0)
            (4.0, 40), // beaten by (4, 30)
            (f64::NAN, 0),
        ];
        assert_eq!(pareto_front(&pts), [false, true, true, false, false, false]);
        // Equal points do not beat each other.
        assert_eq!(pareto_front(&[(1.0, 2), (1.0, 2)]), [true, true]);
        assert!(pareto_front(&[]).is_empty());
    }

    proptest! {
        /// Every point off the front is beaten by one on it, and no point on
        /// it is beaten by any point.
        #[test]
        fn front_members_are_unbeaten_and_beat_the_rest(
            pts in proptest::collection::vec((0.0f64..50.0, 0u64..20), 1..24)
        ) {
            let front = pareto_front(&pts);
            let beats = |a: (f64, u64), b: (f64, u64)| a.0 <= b.0 && a.1 <= b.1 && a != b;
            prop_assert!(front.iter().any(|&f| f));
            for (i, &p) in pts.iter().enumerate() {
                if front[i] {
                    prop_assert!(!pts.iter().any(|&q| beats(q, p)));
                } else {
                    prop_assert!(pts.iter().zip(&front).any(|(&q, &f)| f && beats(q, p)));
                }
            }
        }
    }

    #[test]
    fn labels_of_a_cluster_do_not_overlap() {
        // Twelve variants at almost the same time and no mismatch: the
        // exact variants of a comparison.
        let anchors: Vec<(i32, i32)> = (0..12).map(|k| (400 + 3 * k, 500)).collect();
        let sizes: Vec<(i32, i32)> = (0..12).map(|k| (60 + 5 * k, 16)).collect();
        let area = (80, 40, 940, 556);
        let corners = place_labels(&anchors, &sizes, area, 5);
        let rects: Vec<Rect> = corners
            .iter()
            .zip(&sizes)
            .map(|(&(x, y), &(w, h))| (x, y, x + w, y + h))
            .collect();
        for (i, &a) in rects.iter().enumerate() {
            assert!(a.0 >= area.0 && a.1 >= area.1 && a.2 <= area.2 && a.3 <= area.3);
            for &b in &rects[i + 1..] {
                assert!(!overlaps(a, b), "{a:?} {b:?}");
            }
            for &(x, y) in &anchors {
                assert!(
                    !overlaps(a, (x - 5, y - 5, x + 6, y + 6)),
                    "{a:?} covers a point"
                );
            }
        }
    }
}
