//! Primitive contact wrenches, the rank test and the Ferrari–Canny ε (L1 grasp wrench space).
//!
//! Conventions: `../shared/notes/grasp-quality.md` (the module docs of [`crate::grasp`]
//! repeat them). Papers: Ferrari & Canny, "Planning optimal grasps", ICRA 1992 (ε = radius of
//! the largest origin-centred ball in the convex hull of the primitive wrenches); paper 002
//! (Vahrenkamp et al. 2010) §IV-B scores multi-robot grasps by their wrench space; paper 001
//! (Saut et al. 2010) §IV-A keeps only force-closure grasps.

use nalgebra::{DMatrix, Vector3};
use serde::{Deserialize, Serialize};

use super::hull::{
    depth_exceeds, nearest_facet_depth, ConvexHull, HullError, HullOptions, NearestDepth, Point6,
};

/// At most this many contacts per grasp (a 64-contact grasp with 32 cone edges is 2048
/// primitive wrenches).
pub const MAX_CONTACTS: usize = 64;
/// Fewest friction-cone edges (a cone needs at least 3 to have an interior).
pub const MIN_CONE_EDGES: usize = 3;
/// Most friction-cone edges.
pub const MAX_CONE_EDGES: usize = 32;
/// Singular values below `RANK_RTOL × σ_max` count as zero in the rank test.
pub const RANK_RTOL: f64 = 1e-9;
/// Most hull facets before [`GraspError::Hull`] (`TooManyFacets`); bounds memory (about 230 MB
/// at the measured ≈ 230 bytes per facet, see [`super::hull`]).
pub const MAX_FACETS: usize = 1_000_000;

/// A point contact with friction: the contact point and the **inward** surface normal (the
/// direction of the force the finger applies), both in the object frame. The normal need not be
/// unit; it is normalised.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    pub point: Vector3<f64>,
    pub normal: Vector3<f64>,
}

impl Contact {
    pub fn new(point: Vector3<f64>, normal: Vector3<f64>) -> Contact {
        Contact { point, normal }
    }
}

/// How the wrench space is built.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WrenchSpaceSettings {
    /// Coulomb friction coefficient μ > 0.
    pub mu: f64,
    /// Edges m of the linearised friction cone (3..=32).
    pub cone_edges: usize,
    /// Torque scale λ = 1 / characteristic length. `None`: 1 / (largest distance of a contact
    /// point from the centre), GraspIt!'s 1 / max radius restricted to the contacts (1 when all
    /// contacts are at the centre).
    pub lambda: Option<f64>,
    /// Soft-finger torsional friction γ > 0: adds the wrenches `[0; ±λ γ n_i]` per contact.
    pub soft_finger: Option<f64>,
}

impl Default for WrenchSpaceSettings {
    /// μ = 0.5, m = 8, λ from the contacts, point contacts.
    fn default() -> Self {
        WrenchSpaceSettings {
            mu: 0.5,
            cone_edges: 8,
            lambda: None,
            soft_finger: None,
        }
    }
}

/// The quality of one grasp.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspQuality {
    /// The origin is strictly inside the wrench hull (rank 6 and ε > the numerical floor).
    pub force_closure: bool,
    /// Ferrari–Canny ε (L1): distance from the origin to the nearest hull facet; 0 when not
    /// force closure.
    pub epsilon: f64,
    /// Rank of the 6×N wrench matrix.
    pub rank: usize,
    /// Number of primitive wrenches N.
    pub wrenches: usize,
    /// Facets of the wrench hull (0 when no hull was built: rank < 6 or flat).
    pub facets: usize,
    /// The torque scale λ used.
    pub lambda: f64,
}

/// Invalid input to [`grasp_quality`]; [`GraspError::field`] names the offending field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GraspError {
    #[error("{field}: must be finite")]
    NonFinite { field: String },
    #[error("{field}: normal has zero length")]
    ZeroNormal { field: String },
    #[error("mu: friction coefficient must be finite and > 0, got {0}")]
    Mu(f64),
    #[error("cone_edges: must be in {MIN_CONE_EDGES}..={MAX_CONE_EDGES}, got {0}")]
    ConeEdges(usize),
    #[error("lambda: torque scale must be finite and > 0, got {0}")]
    Lambda(f64),
    #[error("soft_finger: torsional friction γ must be finite and > 0, got {0}")]
    SoftFinger(f64),
    #[error("contacts: {count} contacts, at most {MAX_CONTACTS} are accepted")]
    TooManyContacts { count: usize },
    #[error("{field}: the primitive wrenches overflow (μ, λ, γ or the distance from the centre too large)")]
    Overflow { field: String },
    #[error("contacts: wrench hull: {0}")]
    Hull(HullError),
    /// An error in the contacts of a scene grasp ([`super::score_object_grasps`]); the field is
    /// relative to that grasp.
    #[error("grasp '{grasp}': {error}")]
    InGrasp {
        grasp: String,
        error: Box<GraspError>,
    },
}

impl GraspError {
    /// The offending field: `contacts[2].normal`, `contacts[2].point`, `centre`, `mu`,
    /// `cone_edges`, `lambda`, `soft_finger`, `contacts` ([`quality_of_wrenches`]: `wrenches[i]`).
    pub fn field(&self) -> &str {
        match self {
            GraspError::NonFinite { field }
            | GraspError::ZeroNormal { field }
            | GraspError::Overflow { field } => field,
            GraspError::Mu(_) => "mu",
            GraspError::ConeEdges(_) => "cone_edges",
            GraspError::Lambda(_) => "lambda",
            GraspError::SoftFinger(_) => "soft_finger",
            GraspError::TooManyContacts { .. } | GraspError::Hull(_) => "contacts",
            GraspError::InGrasp { error, .. } => error.field(),
        }
    }

    /// The message without the field prefix (an [`GraspError::InGrasp`] keeps its whole text).
    pub fn reason(&self) -> String {
        let s = self.to_string();
        let prefix = format!("{}: ", self.field());
        s.strip_prefix(&prefix).map(str::to_string).unwrap_or(s)
    }
}

fn finite(v: &Vector3<f64>) -> bool {
    v.iter().all(|c| c.is_finite())
}

impl WrenchSpaceSettings {
    /// Checks μ, the cone edges, λ (when given) and γ (when given); errors name the field.
    pub fn validate(&self) -> Result<(), GraspError> {
        if !(self.mu.is_finite() && self.mu > 0.0) {
            return Err(GraspError::Mu(self.mu));
        }
        if !(MIN_CONE_EDGES..=MAX_CONE_EDGES).contains(&self.cone_edges) {
            return Err(GraspError::ConeEdges(self.cone_edges));
        }
        if let Some(l) = self.lambda {
            if !(l.is_finite() && l > 0.0) {
                return Err(GraspError::Lambda(l));
            }
        }
        if let Some(g) = self.soft_finger {
            if !(g.is_finite() && g > 0.0) {
                return Err(GraspError::SoftFinger(g));
            }
        }
        Ok(())
    }
}

/// Validates the settings and contacts; returns λ.
fn validate(
    contacts: &[Contact],
    centre: &Vector3<f64>,
    s: &WrenchSpaceSettings,
) -> Result<f64, GraspError> {
    s.validate()?;
    if contacts.len() > MAX_CONTACTS {
        return Err(GraspError::TooManyContacts {
            count: contacts.len(),
        });
    }
    if !finite(centre) {
        return Err(GraspError::NonFinite {
            field: "centre".into(),
        });
    }
    let mut rmax = 0.0f64;
    for (i, c) in contacts.iter().enumerate() {
        if !finite(&c.point) {
            return Err(GraspError::NonFinite {
                field: format!("contacts[{i}].point"),
            });
        }
        if !finite(&c.normal) {
            return Err(GraspError::NonFinite {
                field: format!("contacts[{i}].normal"),
            });
        }
        // Finite components: the norm is finite or +∞ (overflow), never NaN.
        let n = c.normal.norm();
        if n <= 1e-12 {
            return Err(GraspError::ZeroNormal {
                field: format!("contacts[{i}].normal"),
            });
        }
        let r = (c.point - centre).norm();
        if !r.is_finite() {
            return Err(GraspError::Overflow {
                field: format!("contacts[{i}].point"),
            });
        }
        rmax = rmax.max(r);
    }
    match s.lambda {
        Some(l) => Ok(l),
        // Contacts so close to the centre that 1 / rmax overflows count as at the centre.
        None if rmax > 0.0 && (1.0 / rmax).is_finite() => Ok(1.0 / rmax),
        None => Ok(1.0),
    }
}

/// Tangents (t1, t2) of a unit normal: t1 from the coordinate axis least aligned with n (the
/// first on ties), t2 = n × t1. Axis-aligned normals get axis-aligned tangents.
pub fn tangents(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let a = n.iamin();
    let mut e = Vector3::zeros();
    e[a] = 1.0;
    let t1 = (e - n * n[a]).normalize();
    (t1, n.cross(&t1))
}

/// Appends the primitive wrenches of `contacts` to `out` (cleared first) and returns λ:
/// for contact i with unit inward normal n_i and cone edge j,
/// f_ij = n_i + μ (cos(2πj/m) t1 + sin(2πj/m) t2) (normal component 1, as GraspIt! and Dex-Net),
/// w_ij = [f_ij ; λ (p_i − c) × f_ij]; with soft fingers also [0 ; ±λ γ n_i].
/// Order: contact-major, edges in angle order, then the two soft-finger wrenches.
pub fn primitive_wrenches_into(
    contacts: &[Contact],
    centre: &Vector3<f64>,
    settings: &WrenchSpaceSettings,
    out: &mut Vec<Point6>,
) -> Result<f64, GraspError> {
    let lambda = validate(contacts, centre, settings)?;
    let m = settings.cone_edges;
    out.clear();
    out.reserve(contacts.len() * (m + 2));
    for (i, c) in contacts.iter().enumerate() {
        let first = out.len();
        // Scaled by the largest component first, so huge normals do not overflow.
        let n = (c.normal / c.normal.amax()).normalize();
        let (t1, t2) = tangents(&n);
        let r = (c.point - centre) * lambda;
        for j in 0..m {
            let a = std::f64::consts::TAU * j as f64 / m as f64;
            let f = n + settings.mu * (a.cos() * t1 + a.sin() * t2);
            let t = r.cross(&f);
            out.push([f.x, f.y, f.z, t.x, t.y, t.z]);
        }
        if let Some(g) = settings.soft_finger {
            let t = n * (lambda * g);
            out.push([0.0, 0.0, 0.0, t.x, t.y, t.z]);
            out.push([0.0, 0.0, 0.0, -t.x, -t.y, -t.z]);
        }
        // Finite inputs can still overflow (a huge μ, λ or γ, or a point far from the centre).
        if out[first..].iter().flatten().any(|x| !x.is_finite()) {
            out.clear();
            return Err(GraspError::Overflow {
                field: format!("contacts[{i}]"),
            });
        }
    }
    Ok(lambda)
}

/// True when the force parts `f` of `wrenches` all lie in one open half-space with a margin —
/// `v·f ≥ 10⁻⁶ |f|` for a unit `v` among their mean direction and each of their directions —
/// so the origin lies outside the wrenches' hull by at least that margin and the grasp is not
/// in force closure: a force-closure grasp's forces push in every direction (its wrench hull
/// holds a ball about the origin, whose force part is a ball; 003 §IV-A-3). Decides most grasps
/// without force closure before any hull; `false` decides nothing.
pub fn forces_one_sided(wrenches: &[Point6]) -> bool {
    let dir = |w: &Point6| {
        let f = Vector3::new(w[0], w[1], w[2]);
        let n = f.norm();
        (n > 0.0 && n.is_finite()).then(|| f / n)
    };
    let mut mean = Vector3::zeros();
    for w in wrenches {
        match dir(w) {
            Some(d) => mean += d,
            // A wrench of no force (a soft finger's torque) is on every half-space's boundary.
            None => return false,
        }
    }
    let separates = |v: Vector3<f64>| {
        let n = v.norm();
        n > 0.0
            && n.is_finite()
            && wrenches.iter().all(|w| {
                let f = Vector3::new(w[0], w[1], w[2]);
                v.dot(&f) / n >= 1e-6 * f.norm()
            })
    };
    separates(mean) || wrenches.iter().filter_map(dir).any(separates)
}

/// The primitive wrenches (see [`primitive_wrenches_into`]).
pub fn primitive_wrenches(
    contacts: &[Contact],
    centre: &Vector3<f64>,
    settings: &WrenchSpaceSettings,
) -> Result<Vec<Point6>, GraspError> {
    let mut out = Vec::new();
    primitive_wrenches_into(contacts, centre, settings, &mut out)?;
    Ok(out)
}

/// Rank of the 6×N matrix of `wrenches` (SVD; singular values ≤ [`RANK_RTOL`] × σ_max are zero).
/// No wrenches, all-zero wrenches or a non-finite coordinate → 0 (an SVD of a matrix holding NaN
/// need not converge, so such input is not decomposed; [`quality_of_wrenches`] rejects it).
pub fn wrench_rank(wrenches: &[Point6]) -> usize {
    if wrenches.is_empty() || wrenches.iter().flatten().any(|c| !c.is_finite()) {
        return 0;
    }
    // The singular values of W (6×N) are those of R in Wᵀ = QR (Householder, backward
    // stable): a 6×6 SVD after an O(36 N) QR instead of the SVD of the wide matrix (about 5×
    // cheaper at N = 160, where the rank was a tenth of the collector's exact score).
    let wt = DMatrix::from_fn(wrenches.len(), 6, |r, c| wrenches[r][c]);
    let sv = wt.qr().r().singular_values();
    // Finite input: the singular values are finite and ≥ 0, so σ_max is never NaN here.
    let smax = sv.iter().copied().fold(0.0f64, f64::max);
    if smax <= 0.0 {
        return 0;
    }
    sv.iter().filter(|&&s| s > RANK_RTOL * smax).count()
}

/// Force closure and the Ferrari–Canny ε of the L1 grasp wrench space of `contacts` about
/// `centre` (the object's centre of mass, same frame as the contacts).
///
/// Steps: validate (errors name the field), build the primitive wrenches, **rank first** (rank
/// < 6 → not force closure, ε = 0: two point contacts never are), then the 6-D convex hull
/// ([`super::hull`]); ε = min over facets of the signed distance of the origin (polished against
/// the unjoggled wrenches, [`ConvexHull::support_depth`]); the origin
/// outside, on, or within the numerical floor `1e-9 × scale` (largest wrench coordinate) of the boundary
/// → not force closure, ε = 0. A flat hull (affine dimension < 6) is not force closure either.
///
/// Cost: N = contacts × (m + 2·soft) wrenches; the rank (a QR of the N×6 transpose and a 6×6
/// SVD, O(36 N)) plus the hull (see [`super::hull`], which dominates): about 1.5 ms for 3
/// contacts and 3.6 ms for 4 contacts with m = 8 in release mode (measured on the 2-core
/// development machine before the hull's pencil planes, which made the 20-contact hull about
/// 2.7× faster).
pub fn grasp_quality(
    contacts: &[Contact],
    centre: &Vector3<f64>,
    settings: &WrenchSpaceSettings,
) -> Result<GraspQuality, GraspError> {
    let mut w = Vec::new();
    let lambda = primitive_wrenches_into(contacts, centre, settings, &mut w)?;
    quality_of_wrenches(&w, lambda)
}

/// The quality before any hull: finite wrenches checked (else [`GraspError::NonFinite`] naming
/// `wrenches[i]`), their rank, no force closure yet.
fn unscored(wrenches: &[Point6], lambda: f64) -> Result<GraspQuality, GraspError> {
    if let Some(i) = wrenches
        .iter()
        .position(|w| w.iter().any(|c| !c.is_finite()))
    {
        return Err(GraspError::NonFinite {
            field: format!("wrenches[{i}]"),
        });
    }
    Ok(GraspQuality {
        force_closure: false,
        epsilon: 0.0,
        rank: wrench_rank(wrenches),
        wrenches: wrenches.len(),
        facets: 0,
        lambda,
    })
}

/// [`grasp_quality`] on given primitive wrenches (`lambda` is only reported). A non-finite
/// coordinate is [`GraspError::NonFinite`] with the field `wrenches[i]`.
pub fn quality_of_wrenches(wrenches: &[Point6], lambda: f64) -> Result<GraspQuality, GraspError> {
    let mut q = unscored(wrenches, lambda)?;
    if q.rank < 6 {
        return Ok(q);
    }
    let opts = HullOptions {
        max_facets: MAX_FACETS,
        ..HullOptions::default()
    };
    let hull = match ConvexHull::with_options(wrenches, &opts) {
        Ok(h) => h,
        Err(HullError::Flat) | Err(HullError::TooFewPoints(_)) => return Ok(q),
        Err(e) => return Err(GraspError::Hull(e)),
    };
    q.facets = hull.facets().len();
    let depth = hull.support_depth(wrenches);
    let floor = 1e-9 * hull.scale();
    if depth > floor {
        q.force_closure = true;
        q.epsilon = depth;
    }
    Ok(q)
}

/// [`quality_of_wrenches`] without the whole hull: the same force-closure verdict and ε (to
/// round-off), from [`nearest_facet_depth`], which grows the hull only toward the origin and
/// polishes the same candidate facets against the unjoggled wrenches; what it cannot decide
/// (the origin on or within the polish slack of the boundary, numerical trouble) is decided by
/// [`quality_of_wrenches`] itself. `facets` counts the facets of the grown hull (the whole hull's
/// when it was needed). Used by the Multi-Robot-RRT collector (002 §IV-B), which scores every
/// combination of 20 contacts.
pub fn quality_of_wrenches_nearest(
    wrenches: &[Point6],
    lambda: f64,
) -> Result<GraspQuality, GraspError> {
    let mut q = unscored(wrenches, lambda)?;
    if q.rank < 6 {
        return Ok(q);
    }
    match nearest_facet_depth(wrenches, MAX_FACETS) {
        Ok(NearestDepth::Inside { depth, facets }) => {
            let scale = wrenches
                .iter()
                .flat_map(|p| p.iter())
                .fold(0.0f64, |m, c| m.max(c.abs()));
            q.facets = facets;
            if depth > 1e-9 * scale {
                q.force_closure = true;
                q.epsilon = depth;
            }
            Ok(q)
        }
        Ok(NearestDepth::Outside { facets }) => {
            q.facets = facets;
            Ok(q)
        }
        Err(HullError::Flat) | Err(HullError::TooFewPoints(_)) => Ok(q),
        Ok(NearestDepth::Undecided) | Ok(NearestDepth::Above { .. }) | Err(_) => {
            quality_of_wrenches(wrenches, lambda)
        }
    }
}

/// The collector's cheap acceptance (002 §IV-B, Alg. 3 line 10): `true` when ε of `wrenches`
/// provably exceeds `s_min` ≥ 0 — rank 6 and [`depth_exceeds`], which stops growing the hull as
/// soon as all of its facets are farther than `s_min` plus the joggle bound — so
/// [`quality_of_wrenches`] would say force closure with ε > `s_min` too. `false` means *not
/// decided*: the exact [`quality_of_wrenches_nearest`] decides (and gives the value).
pub fn score_exceeds_nearest(wrenches: &[Point6], s_min: f64) -> bool {
    if !(s_min.is_finite() && s_min >= 0.0)
        || wrenches.iter().flatten().any(|c| !c.is_finite())
        || wrench_rank(wrenches) < 6
    {
        return false;
    }
    matches!(
        depth_exceeds(wrenches, MAX_FACETS, s_min),
        Ok(NearestDepth::Above { .. })
    )
}
