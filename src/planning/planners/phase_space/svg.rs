//! The phase space as an SVG picture (002 Fig. 9).

use super::PhaseSpace;

/// An SVG of the phase space like 002 Fig. 9: invalid phases sampled on a grid in red, the path
/// in green. Two robots: the square P; three or more: the projections on every pair of phases
/// (a cell is red when some of `resolution` samples along the other phases is invalid).
pub fn phase_space_svg(ps: &mut PhaseSpace, path: &[Vec<f64>], resolution: usize) -> String {
    let n = ps.dim();
    let res = resolution.clamp(4, 200);
    let size = 300.0;
    let pairs: Vec<(usize, usize)> = if n == 1 {
        vec![(0, 0)]
    } else {
        (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .collect()
    };
    let margin = 30.0;
    let width = pairs.len() as f64 * (size + margin) + margin;
    let height = size + 2.0 * margin;
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width:.0}\" height=\"{height:.0}\" \
         viewBox=\"0 0 {width:.0} {height:.0}\" font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    let cell = size / res as f64;
    let third = if n > 2 { res.min(12) } else { 1 };
    let mut phi = vec![0.0; n];
    for (pi, &(a, b)) in pairs.iter().enumerate() {
        let x0 = margin + pi as f64 * (size + margin);
        let y0 = margin;
        svg += &format!(
            "<rect x=\"{x0:.1}\" y=\"{y0:.1}\" width=\"{size}\" height=\"{size}\" fill=\"none\" stroke=\"black\"/>\n"
        );
        for ix in 0..res {
            for iy in 0..res {
                let (u, v) = (
                    (ix as f64 + 0.5) / res as f64,
                    (iy as f64 + 0.5) / res as f64,
                );
                let mut bad = false;
                // Other phases: a grid of `third` values each (all combinations for n = 3).
                let others: Vec<usize> = (0..n).filter(|&k| k != a && k != b).collect();
                let combos = third.pow(others.len() as u32).max(1);
                for c in 0..combos {
                    let mut rest = c;
                    for &k in &others {
                        phi[k] = ((rest % third) as f64 + 0.5) / third as f64;
                        rest /= third;
                    }
                    phi[a] = u;
                    if n > 1 {
                        phi[b] = v;
                    }
                    if !ps.is_valid(&phi) {
                        bad = true;
                        break;
                    }
                }
                if bad {
                    svg += &format!(
                        "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"#d62728\"/>\n",
                        x0 + ix as f64 * cell,
                        y0 + size - (iy + 1) as f64 * cell,
                        cell + 0.05,
                        cell + 0.05
                    );
                }
            }
        }
        let pts: Vec<String> = path
            .iter()
            .map(|p| {
                let v = if n > 1 { p[b] } else { p[a] };
                format!("{:.2},{:.2}", x0 + p[a] * size, y0 + size - v * size)
            })
            .collect();
        svg += &format!(
            "<polyline points=\"{}\" fill=\"none\" stroke=\"#2ca02c\" stroke-width=\"3\"/>\n",
            pts.join(" ")
        );
        svg += &format!(
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">φ{} ({})</text>\n",
            x0 + size / 2.0,
            y0 + size + 18.0,
            a + 1,
            ps.robot_name(a)
        );
        if n > 1 {
            svg += &format!(
                "<text x=\"{:.1}\" y=\"{:.1}\" transform=\"rotate(-90 {:.1} {:.1})\" text-anchor=\"middle\">φ{} ({})</text>\n",
                x0 - 8.0,
                y0 + size / 2.0,
                x0 - 8.0,
                y0 + size / 2.0,
                b + 1,
                ps.robot_name(b)
            );
        }
    }
    svg += "</svg>\n";
    svg
}

impl PhaseSpace {
    /// Name of the robot of phase coordinate `k`.
    pub fn robot_name(&self, k: usize) -> String {
        self.tracks
            .get(k)
            .map(|t| self.world.robots[t.robot].name.clone())
            .unwrap_or_default()
    }
}
