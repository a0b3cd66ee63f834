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
    seconds: Vec<TermSeconds>,
}

/// Wall-clock seconds a term has spent in solves, by phase (reports only).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TermSeconds {
    /// In its substep set-up ([`Term::begin_substep`]: for contacts, finding the pairs).
    pub setup: f64,
    /// In its iterations (projections, or projective dynamics' local step).
    pub iterations: f64,
}

impl TermSeconds {
    /// Both phases.
    pub fn total(self) -> f64 {
        self.setup + self.iterations
    }
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
        self.seconds.insert(index, TermSeconds::default());
        index
    }

    /// Puts `term` in the place of the registered term of its name (keeping its place in
    /// the order and its accumulated seconds); adds it after the others if there is
    /// none.
    pub fn replace(&mut self, term: impl Term) {
        match self.kinds.iter().position(|k| k.name() == term.name()) {
            Some(i) => self.kinds[i] = Box::new(term),
            None => {
                self.register(term);
            }
        }
    }

    /// What the term named `name` holds ([`Term::extent`]); `None` if none is registered.
    pub fn extent(&self, name: &str) -> Option<super::term::TermExtent> {
        self.iter().find(|k| k.name() == name).map(|k| k.extent())
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
    pub(super) fn iter_timed(&mut self) -> impl Iterator<Item = (&mut dyn Term, &mut TermSeconds)> {
        self.kinds
            .iter_mut()
            .map(|k| k.as_mut())
            .zip(self.seconds.iter_mut())
    }

    /// Each term's name and the seconds it has spent in solves, in order.
    pub fn seconds(&self) -> impl Iterator<Item = (&'static str, f64)> + '_ {
        self.phase_seconds().map(|(name, s)| (name, s.total()))
    }

    /// Each term's name and the seconds it has spent in solves by phase, in order.
    pub fn phase_seconds(&self) -> impl Iterator<Item = (&'static str, TermSeconds)> + '_ {
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

    /// Each term's saved state ([`Term::saved_state`]), with its name, in order.
    pub fn saved_states(&self) -> Vec<(String, Vec<u8>)> {
        self.kinds
            .iter()
            .filter_map(|k| Some((k.name().to_string(), k.saved_state()?)))
            .collect()
    }

    /// Gives each saved state to the term of its name ([`Term::resume_state`]); an
    /// error naming the term when no term takes it or it is refused.
    pub fn resume_states(&mut self, states: Vec<(String, Vec<u8>)>) -> Result<(), String> {
        for (name, state) in states {
            let term = self
                .kinds
                .iter_mut()
                .find(|k| k.name() == name)
                .ok_or_else(|| format!("term `{name}`: no such term takes a saved state"))?;
            term.resume_state(&state)
                .map_err(|e| format!("term `{name}`: {e}"))?;
        }
        Ok(())
    }

    /// Every dense particle some term holds kinematic.
    pub fn kinematic(&self) -> impl Iterator<Item = u32> + '_ {
        self.kinds
            .iter()
            .flat_map(|k| k.kinematic().iter().copied())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saved_states_go_back_to_their_terms_and_strangers_are_refused() {
        let mut terms = Terms::builtin();
        let states = terms.saved_states();
        let names: Vec<&str> = states.iter().map(|(n, _)| n.as_str()).collect();
        // the terms that carry state between frames save it; the others are taken
        // again from the ECS
        assert!(
            names.contains(&"oriented") && names.contains(&"patches"),
            "{names:?}"
        );
        assert!(!names.contains(&"colliders"), "{names:?}");
        assert!(terms.resume_states(states).is_ok());
        let e = terms
            .resume_states(vec![("no such term".into(), vec![])])
            .unwrap_err();
        assert!(e.contains("no such term takes"), "{e}");
        let e = terms
            .resume_states(vec![("oriented".into(), vec![0xff; 3])])
            .unwrap_err();
        assert!(e.starts_with("term `oriented`:"), "{e}");
        assert!(terms.get::<Oriented>().is_some());
    }
}
