//! Inverse reachability and base placement (paper 002 = Vahrenkamp et al. 2010, §III-A/B/C).
//!
//! From a reachability grid whose frame is the mobile platform (e.g. `torso_right_arm`: hip +
//! arm), the *inverse reachability map* of a grasp pose g gives, for every base position (x, y)
//! on the floor, how likely g is reachable from there: each base pose B = (x, y, yaw) is tried
//! for `yaw_bins` yaw angles and the entry of B⁻¹·g is looked up (§III-A; our grid does not
//! contain the platform rotation, so the yaw is covered by the loop). Maps of a grasp set are
//! united by the maximum, and every cell keeps the list of grasps reachable from it. The
//! *bimanual map* is R_bi = min(R_left, R_right) (eq. 1, §III-B). [`ik_dual_arm`] is Alg. 1
//! (§III-C): sample a base pose from R_bi, sample the free joints, solve both arms analytically
//! only for the grasps the cell lists, collision-check.

use std::f64::consts::PI;

use nalgebra::{UnitQuaternion, Vector3};
use rand::Rng;
use rayon::prelude::*;

use super::grid::ReachabilityGrid;
use crate::geometry::Pose;
use crate::kinematics::dual_arm::DualArmIk;
use crate::kinematics::randomized::ReachabilityMap;
use crate::kinematics::randomized::{
    solve_psi, IkCounters, RandomizedIkError, RandomizedIkSettings,
};
use crate::kinematics::FkPath;
use crate::model::Robot;

/// A 2-D map over base positions (x, y) and base yaw: per (cell, yaw bin) the best probability and
/// the grasps above the threshold.
#[derive(Debug, Clone)]
pub struct InverseMap {
    /// Lower corner (world x, y) and cell size.
    pub origin: [f64; 2],
    pub cell: f64,
    pub dims: [usize; 2],
    pub yaw_bins: usize,
    /// `value[(ix·ny + iy)·yaw_bins + iw]`.
    pub value: Vec<f32>,
    /// Grasps reachable from each (cell, yaw) (same index as `value`).
    pub grasps: Vec<Vec<u16>>,
}

impl InverseMap {
    /// The layout (origin, cell, dims, yaw bins) without the data, for [`InverseMap::cell_pose`].
    fn clone_layout(&self) -> InverseMap {
        InverseMap {
            origin: self.origin,
            cell: self.cell,
            dims: self.dims,
            yaw_bins: self.yaw_bins,
            value: Vec::new(),
            grasps: Vec::new(),
        }
    }

    /// (x, y) of a cell centre and the yaw of a bin, as values of the base variables (the world's
    /// only for a robot placed at the world origin).
    pub fn cell_pose(&self, ix: usize, iy: usize, iw: usize) -> (f64, f64, f64) {
        (
            self.origin[0] + (ix as f64 + 0.5) * self.cell,
            self.origin[1] + (iy as f64 + 0.5) * self.cell,
            -PI + (iw as f64 + 0.5) * 2.0 * PI / self.yaw_bins as f64,
        )
    }

    /// The 2-D map (maximum over yaw), row-major over (x, y).
    pub fn xy(&self) -> Vec<f32> {
        self.value
            .chunks(self.yaw_bins)
            .map(|c| c.iter().copied().fold(0.0, f32::max))
            .collect()
    }

    /// Largest value.
    pub fn max(&self) -> f32 {
        self.value.iter().copied().fold(0.0, f32::max)
    }
}

/// Platform pose in the world for base (x, y, yaw): the robot's base joints set, through FK.
fn platform_pose(
    path: &FkPath,
    robot_base: &Pose,
    q: &mut [f64],
    base_vars: &[usize; 3],
    (x, y, w): (f64, f64, f64),
) -> Pose {
    q[base_vars[0]] = x;
    q[base_vars[1]] = y;
    q[base_vars[2]] = w;
    robot_base * path.pose(q)
}

/// Where a grid can reach about the base's yaw axis: the axis in the platform frame (point,
/// unit direction) and, over the grid's filled position voxels, the range of their distance to
/// the axis (`rho`) and of their coordinate along it (`h`), widened by half a voxel diagonal.
/// Both are unchanged by the base yaw, so a target outside them has entry 0 at every yaw of a
/// base position (002 §III-A, the yaw loop of [`inverse_map`]).
struct YawReach {
    a: Vector3<f64>,
    u: Vector3<f64>,
    rho: (f64, f64),
    h: (f64, f64),
}

impl YawReach {
    /// `None` when the base yaw does not turn the platform about one fixed line (then every
    /// base pose is looked up).
    fn new(
        path: &FkPath,
        robot_base: &Pose,
        q: &mut [f64],
        base_vars: &[usize; 3],
        grid: &ReachabilityGrid,
    ) -> Option<YawReach> {
        let at =
            |q: &mut [f64], w: f64| platform_pose(path, robot_base, q, base_vars, (0.0, 0.0, w));
        let p0 = at(q, 0.0);
        // A quarter turn is a rotation by π/2 about the axis; Chasles: the axis passes through
        // (t + u × t) / 2 for a translation t normal to it.
        let t01 = p0.inverse() * at(q, 0.5 * PI);
        let (u, angle) = t01.rotation.axis_angle()?;
        let t = t01.translation.vector;
        if (angle - 0.5 * PI).abs() > 1e-9 || t.dot(&u).abs() > 1e-9 {
            return None;
        }
        let a = 0.5 * (t + u.cross(&t));
        // The same line for other yaws, or no pruning.
        for w in [1.0, -2.5, 3.0] {
            let about = Pose::from_parts(a.into(), UnitQuaternion::identity());
            let turn = Pose::from_parts(
                Vector3::zeros().into(),
                UnitQuaternion::from_axis_angle(&u, w),
            );
            let expect = p0 * about * turn * about.inverse();
            let got = at(q, w);
            if (expect.translation.vector - got.translation.vector).norm() > 1e-9
                || expect.rotation.angle_to(&got.rotation) > 1e-9
            {
                return None;
            }
        }
        let u = u.into_inner();
        let slack = 0.5 * 3f64.sqrt() * grid.params().resolution + 1e-9;
        let mut rho = (f64::INFINITY, f64::NEG_INFINITY);
        let mut h = rho;
        for c in grid.filled_positions() {
            let d = c - a;
            let along = d.dot(&u);
            let r = (d - u * along).norm();
            rho = (rho.0.min(r), rho.1.max(r));
            h = (h.0.min(along), h.1.max(along));
        }
        Some(YawReach {
            a,
            u,
            rho: (rho.0 - slack, rho.1 + slack),
            h: (h.0 - slack, h.1 + slack),
        })
    }

    /// Whether a point, given in the frame of the platform at yaw 0, can fall in a filled
    /// position voxel at some yaw.
    #[inline]
    fn may_reach(&self, p: &Vector3<f64>) -> bool {
        let d = p - self.a;
        let along = d.dot(&self.u);
        if along < self.h.0 || along > self.h.1 {
            return false;
        }
        let r2 = (d - self.u * along).norm_squared();
        r2 <= self.rho.1 * self.rho.1 && (self.rho.0 <= 0.0 || r2 >= self.rho.0 * self.rho.0)
    }
}

/// Inverse reachability map of a grasp set (002 §III-A): grasp poses `targets` (world), the
/// platform-frame `grid` (its base link is the platform), base positions within `radius` of
/// `centre` (world x, y) on a `cell` grid, `yaw_bins` base yaws; union over the grasps by maximum
/// (maps to be combined by [`bimanual`] need the same centre, radius, cell and yaw bins).
#[allow(clippy::too_many_arguments)]
pub fn inverse_map(
    robot: &Robot,
    robot_base: &Pose,
    start: &[f64],
    base_vars: &[usize; 3],
    grid: &ReachabilityGrid,
    targets: &[Pose],
    centre: [f64; 2],
    cell: f64,
    radius: f64,
    yaw_bins: usize,
    threshold: f64,
) -> Option<InverseMap> {
    let platform = robot.link(grid.base_link())?;
    if targets.is_empty() || !(cell > 0.0 && radius > 0.0 && radius / cell < 10_000.0) {
        return None;
    }
    let n = ((2.0 * radius / cell).ceil() as usize).max(1);
    let yaw_bins = yaw_bins.max(1);
    let origin = [centre[0] - radius, centre[1] - radius];
    let mut map = InverseMap {
        origin,
        cell,
        dims: [n, n],
        yaw_bins,
        value: vec![0.0; n * n * yaw_bins],
        grasps: vec![Vec::new(); n * n * yaw_bins],
    };
    // Rows of cells in parallel (rayon); each row writes only its own slice, so the result does
    // not depend on the thread count.
    let row = n * yaw_bins;
    let layout = map.clone_layout();
    let path = FkPath::new(robot, platform);
    let reach = YawReach::new(&path, robot_base, &mut start.to_vec(), base_vars, grid);
    // The platform's rotation at each yaw bin (taken at the first cell) and, for every target,
    // its position turned by it and the orientation part of its grid cell under it. A base pose
    // whose rotation is bit for bit the same (every cell of a planar base, where x and y only
    // translate) then needs one addition and a position lookup per target, with the very
    // values the full lookup computes; other base poses take the full lookup.
    let g_count = targets.len();
    let mut yaw_rot = Vec::with_capacity(yaw_bins);
    let mut rot_off = Vec::with_capacity(yaw_bins * g_count);
    let mut turned = Vec::with_capacity(yaw_bins * g_count);
    {
        let mut q = start.to_vec();
        for iw in 0..yaw_bins {
            let xyw = layout.cell_pose(0, 0, iw);
            let r = platform_pose(&path, robot_base, &mut q, base_vars, xyw)
                .inverse()
                .rotation;
            yaw_rot.push(r);
            rot_off.extend(
                targets
                    .iter()
                    .map(|t| grid.rotation_offset(&(r * t.rotation))),
            );
            turned.extend(targets.iter().map(|t| r * t.translation.vector));
        }
    }
    map.value
        .par_chunks_mut(row)
        .zip(map.grasps.par_chunks_mut(row))
        .enumerate()
        .for_each(|(ix, (values, lists))| {
            let mut q = start.to_vec();
            let mut probs = vec![0.0; targets.len()];
            // The targets that may be reachable from a base position at some yaw.
            let mut near: Vec<Pose> = Vec::with_capacity(targets.len());
            let mut index: Vec<u16> = Vec::with_capacity(targets.len());
            for iy in 0..n {
                near.clear();
                index.clear();
                let (x, y, _) = layout.cell_pose(ix, iy, 0);
                let inv0 =
                    platform_pose(&path, robot_base, &mut q, base_vars, (x, y, 0.0)).inverse();
                for (g, t) in targets.iter().enumerate() {
                    let p = inv0.transform_point(&t.translation.vector.into()).coords;
                    if reach.as_ref().is_none_or(|r| r.may_reach(&p)) {
                        near.push(*t);
                        index.push(g as u16);
                    }
                }
                if near.is_empty() {
                    continue;
                }
                for iw in 0..yaw_bins {
                    let xyw = layout.cell_pose(ix, iy, iw);
                    let inv = platform_pose(&path, robot_base, &mut q, base_vars, xyw).inverse();
                    let k = iy * yaw_bins + iw;
                    let probs = &mut probs[..near.len()];
                    let r0 = &yaw_rot[iw];
                    if r0
                        .coords
                        .iter()
                        .zip(inv.rotation.coords.iter())
                        .all(|(a, b)| a == b)
                    {
                        // Same rotation as the yaw bin's: positions only.
                        let offs = &rot_off[iw * g_count..(iw + 1) * g_count];
                        let turned = &turned[iw * g_count..(iw + 1) * g_count];
                        for (&g, p) in index.iter().zip(probs.iter_mut()) {
                            let pos = turned[g as usize] + inv.translation.vector;
                            *p = grid.probability_with_rotation(&pos, offs[g as usize]);
                        }
                    } else {
                        grid.probabilities(&inv, &near, probs);
                    }
                    for (&g, &p) in index.iter().zip(probs.iter()) {
                        if p > threshold {
                            values[k] = values[k].max(p as f32);
                            lists[k].push(g);
                        }
                    }
                }
            }
        });
    Some(map)
}

/// The bimanual map R_bi = min(R_left, R_right) (002 eq. 1), keeping both grasp lists per cell.
/// Returns the map (values) and the left and right lists. `None` if the maps differ in layout.
pub fn bimanual(left: &InverseMap, right: &InverseMap) -> Option<(InverseMap, Vec<Vec<u16>>)> {
    if left.dims != right.dims || left.yaw_bins != right.yaw_bins || left.origin != right.origin {
        return None;
    }
    let mut bi = left.clone();
    for k in 0..bi.value.len() {
        bi.value[k] = left.value[k].min(right.value[k]);
        if bi.value[k] <= 0.0 {
            bi.grasps[k].clear();
        }
    }
    let rights = (0..bi.value.len())
        .map(|k| {
            if bi.value[k] > 0.0 {
                right.grasps[k].clone()
            } else {
                Vec::new()
            }
        })
        .collect();
    Some((bi, rights))
}

/// The right arm's answer for one right grasp in one [`ik_dual_arm`] try: `None` until solved,
/// then the number of solutions and the solutions.
type RightSlot = Option<(usize, [[f64; 7]; 8])>;

/// A base-placement dual-arm answer: full configuration (base + hip + both arms).
#[derive(Debug, Clone, PartialEq)]
pub struct BasePlacement {
    pub config: Vec<f64>,
    pub left_grasp: usize,
    pub right_grasp: usize,
    pub counters: IkCounters,
}

/// The cumulative distribution of a map's values over (cell, yaw bin), in the order of
/// `value`: what [`ik_dual_arm`] samples base poses from (∝ R_bi). Build it once per map.
pub fn placement_cdf(map: &InverseMap) -> Vec<f64> {
    let mut acc = 0.0f64;
    map.value
        .iter()
        .map(|&v| {
            acc += v.max(0.0) as f64;
            acc
        })
        .collect()
}

/// IkDualArm (002 Alg. 1): sample a base pose (x, y within the cell, yaw within the bin) from the
/// bimanual map with probability ∝ R_bi, sample the free (hip) joints, solve both arms
/// analytically (up to `settings.psi_samples` swivel angles each) only for the grasps that cell lists (left `targets_left[g]`, right
/// `targets_right[g]`, world poses), and return the first collision-free combination. `cdf` is
/// [`placement_cdf`] of `bi` (no solution when its length differs).
#[allow(clippy::too_many_arguments)]
pub fn ik_dual_arm<R: Rng + ?Sized>(
    ik: &DualArmIk,
    robot_base: &Pose,
    start: &[f64],
    base_vars: &[usize; 3],
    bi: &InverseMap,
    cdf: &[f64],
    rights: &[Vec<u16>],
    targets_left: &[Pose],
    targets_right: &[Pose],
    settings: &RandomizedIkSettings,
    rng: &mut R,
    valid: impl FnMut(&[f64]) -> bool,
) -> Result<BasePlacement, RandomizedIkError> {
    ik_dual_arm_filtered(
        ik,
        robot_base,
        start,
        base_vars,
        bi,
        cdf,
        rights,
        targets_left,
        targets_right,
        settings,
        rng,
        |_| true,
        valid,
    )
}

/// [`ik_dual_arm`] with a test of the sampled base pose before any arm is solved:
/// `base_valid(q)` sees the robot configuration with the base variables of the try set (the
/// other variables as left by the previous try or `start`) and must return `false` only when
/// *no* configuration with that base pose can pass `valid` — e.g. the platform alone collides
/// with an obstacle, or the base is outside the planner's bounds. Such a try is skipped without
/// solving either arm; the answers are those `valid` accepts, as in [`ik_dual_arm`].
#[allow(clippy::too_many_arguments)]
pub fn ik_dual_arm_filtered<R: Rng + ?Sized>(
    ik: &DualArmIk,
    robot_base: &Pose,
    start: &[f64],
    base_vars: &[usize; 3],
    bi: &InverseMap,
    cdf: &[f64],
    rights: &[Vec<u16>],
    targets_left: &[Pose],
    targets_right: &[Pose],
    settings: &RandomizedIkSettings,
    rng: &mut R,
    mut base_valid: impl FnMut(&[f64]) -> bool,
    mut valid: impl FnMut(&[f64]) -> bool,
) -> Result<BasePlacement, RandomizedIkError> {
    let robot = ik.robot().clone();
    if start.len() != robot.dof() {
        return Err(RandomizedIkError::BadStart {
            found: start.len(),
            expected: robot.dof(),
        });
    }
    let mut c = IkCounters::default();
    let acc = cdf.last().copied().unwrap_or(0.0);
    if cdf.len() != bi.value.len() || acc <= 0.0 {
        return Err(RandomizedIkError::NoSolution {
            tries: 0,
            counters: c,
        });
    }
    let mut q = start.to_vec();
    let wbin = 2.0 * PI / bi.yaw_bins as f64;
    let mut sols_l = [[0.0; 7]; 8];
    // Right-arm answers of the current try, one slot per entry of the cell's right list:
    // solved at most once per try (the right arm's IK does not depend on the left arm's joints).
    let mut right: Vec<RightSlot> = Vec::new();
    for _ in 0..settings.max_tries {
        c.tries += 1;
        let u = rng.random_range(0.0..acc);
        let k = cdf.partition_point(|&v| v <= u).min(cdf.len() - 1);
        let (iw, cell) = (k % bi.yaw_bins, k / bi.yaw_bins);
        let (ix, iy) = (cell / bi.dims[1], cell % bi.dims[1]);
        let (x, y, w) = bi.cell_pose(ix, iy, iw);
        q[base_vars[0]] = x + rng.random_range(-0.5..0.5) * bi.cell;
        q[base_vars[1]] = y + rng.random_range(-0.5..0.5) * bi.cell;
        q[base_vars[2]] = w + rng.random_range(-0.5..0.5) * wbin;
        if !base_valid(&q) {
            c.rejected_bases += 1;
            continue;
        }
        robot.sample_vars(ik.free_vars(), &mut q, rng);
        let (linv, rinv) = ik.base_inverses(robot_base, &q);
        let rlist = &rights[k];
        right.clear();
        right.resize(rlist.len(), None);
        let solve_right =
            |j: usize, right: &mut Vec<RightSlot>, c: &mut IkCounters, rng: &mut R| {
                if right[j].is_none() {
                    right[j] = Some(match targets_right.get(rlist[j] as usize) {
                        Some(tr) => {
                            let mut sols = [[0.0; 7]; 8];
                            let n = solve_psi(
                                &ik.right().arm,
                                &(rinv * tr),
                                settings.psi_samples,
                                &mut sols,
                                c,
                                rng,
                            );
                            (n, sols)
                        }
                        None => (0, [[0.0; 7]; 8]),
                    });
                }
            };
        // A try whose right arm reaches none of the cell's right grasps cannot succeed: find the
        // first right answer before any left solve (the others are solved when first needed).
        let mut any_right = false;
        for j in 0..rlist.len() {
            solve_right(j, &mut right, &mut c, rng);
            if matches!(right[j], Some((n, _)) if n > 0) {
                any_right = true;
                break;
            }
        }
        if !any_right {
            continue;
        }
        for &gl in &bi.grasps[k] {
            let Some(tl) = targets_left.get(gl as usize) else {
                continue;
            };
            let nl = solve_psi(
                &ik.left().arm,
                &(linv * tl),
                settings.psi_samples,
                &mut sols_l,
                &mut c,
                rng,
            );
            if nl == 0 {
                continue;
            }
            ik.left()
                .arm
                .to_config(&sols_l[rng.random_range(0..nl)], &mut q);
            for j in 0..rlist.len() {
                solve_right(j, &mut right, &mut c, rng);
                let Some((nr, sols_r)) = &right[j] else {
                    continue;
                };
                for s in &sols_r[..*nr] {
                    ik.right().arm.to_config(s, &mut q);
                    c.collision_checks += 1;
                    if valid(&q) {
                        return Ok(BasePlacement {
                            config: q,
                            left_grasp: gl as usize,
                            right_grasp: rlist[j] as usize,
                            counters: c,
                        });
                    }
                }
            }
        }
    }
    Err(RandomizedIkError::NoSolution {
        tries: c.tries,
        counters: c,
    })
}
