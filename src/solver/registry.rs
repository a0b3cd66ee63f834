//! The registered terms, in the order they are projected, with the time each has taken.

use super::term::{Term, Topology};
use super::terms::attachments::Attachments;
use super::terms::centroids::Centroids;
use super::terms::colliders::Colliders;
use super::terms::contacts::Contacts;
use super::terms::edges::Edges;
use super::terms::oriented::Oriented;
use super::terms::patches::Patches;
use std::any::Any;

/// Every term besides the clusters, in projection order; see [`super::term`].
#[derive(Default)]
pub struct Terms {
    kinds: Vec<Box<dyn Term>>,
    /// Wall-clock seconds each term has spent in solves (reports only).
    seconds: Vec<f64>,
}

impl std::fmt::Debug for Terms {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list()
            .entries(self.kinds.iter().map(|k| k.name()))
            .finish()
    }
}

impl Terms {
    /// The built-in kinds: one line each. Attachments first, so that the particles they
    /// hold are in place before anything reads them; then the oriented particles' groups,
    /// the elasticity of their bodies as the clusters are of the others; patches before the centroid holds,
    /// so that a hard hold is met after the soft patches have moved its particles;
    /// colliders last, so that no other kind leaves a particle inside one.
    pub fn builtin() -> Self {
        let mut terms = Terms::default();
        terms.register(Attachments::default());
        terms.register(Oriented::default());
        terms.register(Patches::default());
        terms.register(Centroids::default());
        terms.register(Edges::default());
        terms.register(Contacts::default());
        terms.register(Colliders::default());
        terms
    }

    /// Adds `term` after the others; returns its place.
    pub fn register(&mut self, term: impl Term) -> usize {
        self.insert(self.kinds.len(), Box::new(term))
    }

    /// Adds `term` at place `index` (clamped to the end).
    pub fn insert(&mut self, index: usize, term: Box<dyn Term>) -> usize {
        let index = index.min(self.kinds.len());
        self.kinds.insert(index, term);
        self.seconds.insert(index, 0.0);
        index
    }

    /// The first registered term of type `T`.
    pub fn get<T: Term>(&self) -> Option<&T> {
        self.kinds
            .iter()
            .find_map(|k| (k.as_ref() as &dyn Any).downcast_ref::<T>())
    }

    /// The first registered term of type `T`, to change it.
    pub fn get_mut<T: Term>(&mut self) -> Option<&mut T> {
        self.kinds
            .iter_mut()
            .find_map(|k| (k.as_mut() as &mut dyn Any).downcast_mut::<T>())
    }

    /// The terms in order.
    pub fn iter(&self) -> impl Iterator<Item = &dyn Term> {
        self.kinds.iter().map(|k| k.as_ref())
    }

    /// The terms in order, each with its accumulated seconds.
    pub(super) fn iter_timed(&mut self) -> impl Iterator<Item = (&mut dyn Term, &mut f64)> {
        self.kinds
            .iter_mut()
            .map(|k| k.as_mut())
            .zip(self.seconds.iter_mut())
    }

    /// Each term's name and the seconds it has spent in solves, in order.
    pub fn seconds(&self) -> impl Iterator<Item = (&'static str, f64)> + '_ {
        self.kinds
            .iter()
            .map(|k| k.name())
            .zip(self.seconds.iter().copied())
    }

    /// Tells every term of a topology change.
    pub fn topology(&mut self, change: &Topology) {
        for k in &mut self.kinds {
            k.topology(change);
        }
    }

    /// Every dense particle some term holds kinematic.
    pub fn kinematic(&self) -> impl Iterator<Item = u32> + '_ {
        self.kinds
            .iter()
            .flat_map(|k| k.kinematic().iter().copied())
    }
}
