//! An SVG picture of a 2-D slice of a reachability grid, like paper 000 Fig. 2a and paper 002
//! Fig. 3a: one plane through the position cells, every cell coloured by the mean (or maximum) of
//! its entries over all orientation bins — colour intensity ∝ reachability.

use std::fmt::Write;

use super::grid::ReachabilityGrid;

/// Which slice to draw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SliceAxes {
    /// The position axis held fixed: 0 = x (draw y–z), 1 = y (draw x–z), 2 = z (draw x–y).
    pub normal: usize,
    /// Coordinate (m, chain-base frame) of the slice along `normal`.
    pub at: f64,
    /// Maximum over orientations instead of the mean.
    pub max: bool,
}

/// The slice as an SVG document (hand-written SVG: rectangles, axes labels, colour bar; colour
/// intensity ∝ √(value / largest value of the slice)).
pub fn slice_svg(grid: &ReachabilityGrid, axes: &SliceAxes) -> String {
    let p = grid.params();
    let d = grid.dims();
    let n = axes.normal.min(2);
    let (a, b) = match n {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let k = (((axes.at - p.min[n]) / p.resolution).floor().max(0.0) as usize).min(d[n] - 1);
    let rb = p.rot_bins as usize;
    let per = rb * rb * rb;
    let data = grid.data();
    let max_e = grid.max_entry().max(1) as f64;
    let mut vals = vec![0.0f64; d[a] * d[b]];
    let mut top = 0.0f64;
    for i in 0..d[a] {
        for j in 0..d[b] {
            let mut c = [0usize; 6];
            c[n] = k;
            c[a] = i;
            c[b] = j;
            let start = grid.index(&c);
            let cells = &data[start..start + per];
            let v = if axes.max {
                cells.iter().copied().max().unwrap_or(0) as f64 / max_e
            } else {
                cells.iter().map(|&e| e as f64).sum::<f64>() / (per as f64 * max_e)
            };
            vals[i * d[b] + j] = v;
            top = top.max(v);
        }
    }
    let px = (600.0 / d[a].max(d[b]) as f64).clamp(2.0, 40.0);
    let (w, h) = (d[a] as f64 * px, d[b] as f64 * px);
    let (ml, mt, mr, mb) = (60.0, 50.0, 90.0, 50.0);
    let names = ["x", "y", "z"];
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}" height="{:.0}" font-family="sans-serif" font-size="12">"#,
        w + ml + mr,
        h + mt + mb
    );
    let _ = writeln!(
        s,
        r#"<rect width="100%" height="100%" fill="white"/><text x="{ml}" y="20">reachability of {} {} ({}→{}), {} = {:.3} m, {} over orientations, {} samples</text>"#,
        grid.robot(),
        grid.group(),
        grid.base_link(),
        grid.tip_link(),
        names[n],
        p.min[n] + (k as f64 + 0.5) * p.resolution,
        if axes.max { "max" } else { "mean" },
        p.samples
    );
    let norm = if top > 0.0 { 1.0 / top } else { 0.0 };
    for i in 0..d[a] {
        for j in 0..d[b] {
            // Square root: the distribution is heavy-tailed, keep the low entries visible.
            let v = (vals[i * d[b] + j] * norm).sqrt();
            if v <= 0.0 {
                continue;
            }
            // White → dark red with intensity ∝ value.
            let g = (255.0 * (1.0 - v)).round() as u8;
            let _ = writeln!(
                s,
                r#"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="rgb(255,{g},{g})"/>"#,
                ml + i as f64 * px,
                mt + h - (j as f64 + 1.0) * px,
                px + 0.05,
                px + 0.05
            );
        }
    }
    let _ = writeln!(
        s,
        r#"<rect x="{ml}" y="{mt}" width="{w:.1}" height="{h:.1}" fill="none" stroke="black"/>"#
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{} [m]: {:.2} … {:.2}</text>"#,
        ml + w / 2.0,
        mt + h + 30.0,
        names[a],
        p.min[a],
        p.max[a]
    );
    let _ = writeln!(
        s,
        r#"<text x="20" y="{:.1}" transform="rotate(-90 20 {:.1})" text-anchor="middle">{} [m]: {:.2} … {:.2}</text>"#,
        mt + h / 2.0,
        mt + h / 2.0,
        names[b],
        p.min[b],
        p.max[b]
    );
    // Colour bar.
    for t in 0..10 {
        let v = 1.0 - t as f64 / 9.0;
        let g = (255.0 * (1.0 - v)).round() as u8;
        let _ = writeln!(
            s,
            r#"<rect x="{:.1}" y="{:.1}" width="20" height="{:.1}" fill="rgb(255,{g},{g})" stroke="gray"/>"#,
            ml + w + 20.0,
            mt + t as f64 * h / 10.0,
            h / 10.0
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}">{:.3}</text><text x="{:.1}" y="{:.1}">0</text>"#,
        ml + w + 45.0,
        mt + 12.0,
        top,
        ml + w + 45.0,
        mt + h
    );
    s.push_str("</svg>\n");
    s
}
