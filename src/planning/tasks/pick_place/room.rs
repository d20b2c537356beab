//! Room for the hands at the key configurations: the configuration search of 003 §V-C accepts
//! a grasp, exchange or place configuration only where the hand can then close on the object
//! or open from it ([`super::configurations::HandRoom`]).
//!
//! 003 checks each key configuration with the hand already closed on the object; the motion
//! chain ([`super::task`]) then needs a *pre-shape* of the hand there, free of the scene, of the
//! other hand and of the object (the hand may not touch what it does not hold yet), from which
//! a certified closing motion reaches the grasp ([`super::fingers`]). A configuration without
//! one would end the chain and re-run the whole search without that grasp; here the search asks
//! first, with the chain's own test ([`first_free`]) in the chain's own worlds, so a search
//! returns key configurations the chain can use.

use std::collections::HashMap;

use super::configurations::{HandRoom, Holder};
use super::fingers::FingerPath;
use super::hands::with_fingers;
use super::{ArmHand, PickPlaceProblem};
use crate::collision::{CollisionChecker, CollisionWorld, ExactChecker, FastChecker};
use crate::grasp::double_grasp::{hand_free_of, Environment};
use crate::grasp::GraspList;
use crate::planning::planners::roadmap_query::attach_at_link;

/// One test of [`first_free`].
pub(super) enum Test<'q> {
    /// Is the configuration free in the world where the motion starts (exact and fast checker)?
    Free(&'q [f64]),
    /// Is the straight motion certified in the world where the hand moves on the object?
    Motion(&'q [f64], &'q [f64]),
}

/// The first of `motions` (hand-variable paths, pre-shape first) that `ah` can make with the
/// arm at `q`: its pre-shape passes [`Test::Free`] and each of its segments [`Test::Motion`];
/// as world configurations. The motion chain's test of a closing motion, and the search's.
pub(super) fn first_free(
    ah: &ArmHand,
    q: &[f64],
    motions: &[FingerPath],
    check: &mut dyn FnMut(Test) -> bool,
) -> Option<Vec<Vec<f64>>> {
    'candidates: for m in motions {
        let path: Vec<Vec<f64>> = m.iter().map(|v| with_fingers(ah, q, v)).collect();
        if !check(Test::Free(&path[0])) {
            continue;
        }
        for s in path.windows(2) {
            if !check(Test::Motion(&s[0], &s[1])) {
                continue 'candidates;
            }
        }
        return Some(path);
    }
    None
}

/// A world and its checkers, built when first used.
struct Checked {
    world: CollisionWorld,
    exact: Option<ExactChecker>,
    fast: Option<FastChecker>,
    /// Its fixed bodies for [`HandRoom::hand_alone`] (`None` inside: the world allows pairs,
    /// so the hand alone is not tested).
    alone: Option<Option<Environment>>,
}

impl Checked {
    fn new(world: CollisionWorld) -> Checked {
        Checked {
            world,
            exact: None,
            fast: None,
            alone: None,
        }
    }

    fn environment(&mut self) -> Option<&Environment> {
        let w = &self.world;
        self.alone
            .get_or_insert_with(|| w.allowed.is_empty().then(|| Environment::new(&w.statics)))
            .as_ref()
    }

    fn free(&mut self, q: &[f64]) -> bool {
        // The fast checker first: it is conservative (a state it finds free is free) and far
        // cheaper, so the exact checker only confirms the states it lets through.
        let w = &self.world;
        self.fast
            .get_or_insert_with(|| FastChecker::new(w))
            .is_free(q)
            && self
                .exact
                .get_or_insert_with(|| ExactChecker::new(w))
                .is_free(q)
    }

    fn motion(&mut self, a: &[f64], b: &[f64]) -> bool {
        let w = &self.world;
        self.fast
            .get_or_insert_with(|| FastChecker::new(w))
            .motion_certified(a, b)
    }
}

/// Which world of [`SceneRoom`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Where {
    /// The object resting at q_o^i.
    Initial,
    /// Resting at q_o^f.
    Final,
    /// Held by pick grasp `a`, the pick hand touching it.
    Pick(usize),
    /// Held by pick grasp `a`, both hands touching it.
    Both(usize),
    /// Held by place grasp `b`, the place hand touching it.
    Place(usize),
}

/// [`HandRoom`] of the task's scene: the chain's worlds (object resting at q_o^i, held by one
/// hand or both, resting at q_o^f) per grasp, their checkers built once per task, and the
/// closable grasps' candidate closing motions ([`super::hands::closable`]).
pub(super) struct SceneRoom<'a> {
    p: &'a PickPlaceProblem,
    initial: &'a CollisionWorld,
    lists: [&'a GraspList; 2],
    motions: [&'a [Vec<FingerPath>]; 2],
    worlds: HashMap<Where, Option<Checked>>,
}

impl<'a> SceneRoom<'a> {
    /// `initial`: the task's world (object resting at q_o^i); the lists and motions of the pick
    /// and the place hand.
    pub(super) fn new(
        p: &'a PickPlaceProblem,
        initial: &'a CollisionWorld,
        lists: [&'a GraspList; 2],
        motions: [&'a [Vec<FingerPath>]; 2],
    ) -> SceneRoom<'a> {
        SceneRoom {
            p,
            initial,
            lists,
            motions,
            worlds: HashMap::new(),
        }
    }

    /// The world `w` (`None` when it cannot be built: the grasp does not exist).
    fn build(&self, w: Where) -> Option<CollisionWorld> {
        let p = self.p;
        let attach = |ah: &ArmHand, side: usize, g: usize, touch: Vec<usize>| {
            let grasp = self.lists[side].grasps.get(g)?;
            attach_at_link(
                self.initial,
                &p.object_name,
                0,
                ah.hand.palm,
                &grasp.palm_pose().inverse(),
                &p.rest,
                touch,
            )
            .ok()
        };
        match w {
            Where::Initial => Some(self.initial.clone()),
            Where::Final => {
                let mut f = self.initial.clone();
                let s = f.statics.iter_mut().find(|s| s.name == p.object_name)?;
                s.pose = p.final_pose;
                Some(f)
            }
            Where::Pick(a) => attach(&p.pick, 0, a, p.pick.links.clone()),
            Where::Both(a) => {
                let mut both = p.pick.links.clone();
                both.extend(p.place.links.iter().copied());
                attach(&p.pick, 0, a, both)
            }
            Where::Place(b) => attach(&p.place, 1, b, p.place.links.clone()),
        }
    }

    /// World `w` and its checkers (built on first use; `None`: it cannot be built).
    fn checked(&mut self, w: Where) -> Option<&mut Checked> {
        if !self.worlds.contains_key(&w) {
            let built = self.build(w).map(Checked::new);
            self.worlds.insert(w, built);
        }
        self.worlds.get_mut(&w)?.as_mut()
    }

    /// The pick (`side` 0) or the place hand.
    fn arm_hand(&self, side: usize) -> &'a ArmHand {
        if side == 0 {
            &self.p.pick
        } else {
            &self.p.place
        }
    }

    /// Can `side`'s hand (0: pick, 1: place) make one of grasp `g`'s closing motions at `q`,
    /// starting free in world `state` and moving in world `motion`?
    fn room(&mut self, side: usize, g: usize, q: &[f64], state: Where, motion: Where) -> bool {
        for w in [state, motion] {
            self.checked(w);
        }
        let Some(motions) = self.motions[side].get(g) else {
            return false;
        };
        let ah = self.arm_hand(side);
        // Two entries of one map, borrowed one at a time inside the test.
        let worlds = &mut self.worlds;
        first_free(ah, q, motions, &mut |t| {
            let (w, test) = match t {
                Test::Free(x) => (state, Test::Free(x)),
                Test::Motion(a, b) => (motion, Test::Motion(a, b)),
            };
            match (worlds.get_mut(&w), test) {
                (Some(Some(c)), Test::Free(x)) => c.free(x),
                (Some(Some(c)), Test::Motion(a, b)) => c.motion(a, b),
                _ => false,
            }
        })
        .is_some()
    }
}

impl HandRoom for SceneRoom<'_> {
    /// Some candidate pre-shape of the grasp, the hand alone with its palm at the grasp's pose,
    /// is free (exact shapes) of every fixed body of the world where the closing motion starts
    /// (the object resting at q_o^i) or the opening motion ends (at q_o^f): the hand-only part
    /// of [`first_free`]'s [`Test::Free`], whose exact checker tests the whole robot in that
    /// world.
    fn hand_alone(&mut self, holder: Holder, g: usize) -> bool {
        let (side, w, pose) = match holder {
            Holder::Pick => (0, Where::Initial, self.p.initial),
            Holder::Place => (1, Where::Final, self.p.final_pose),
        };
        let (lists, motions, ah) = (self.lists, self.motions, self.arm_hand(side));
        let (Some(grasp), Some(motions)) = (lists[side].grasps.get(g), motions[side].get(g)) else {
            return true;
        };
        let Some(env) = self.checked(w).and_then(Checked::environment) else {
            return true;
        };
        let palm = pose * grasp.palm_pose();
        motions
            .iter()
            .filter_map(|m| m.first())
            .any(|pre| hand_free_of(&ah.hand, pre, &palm, env))
    }

    fn grasp(&mut self, g: usize, q: &[f64]) -> bool {
        self.room(0, g, q, Where::Initial, Where::Pick(g))
    }

    fn exchange(&mut self, a: usize, b: usize, q: &[f64]) -> bool {
        self.room(1, b, q, Where::Pick(a), Where::Both(a))
            && self.room(0, a, q, Where::Place(b), Where::Both(a))
    }

    fn place(&mut self, b: usize, q: &[f64]) -> bool {
        self.room(1, b, q, Where::Final, Where::Place(b))
    }
}
