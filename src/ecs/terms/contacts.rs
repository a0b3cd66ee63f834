//! The contacts' ECS side: the simulation's `contacts` and `culling` settings.

use crate::ecs::ecs_term::EcsTerm;
use crate::ecs::resources::SimSettings;
use crate::solver::terms::contacts::Contacts;
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParamItem;

impl EcsTerm for Contacts {
    type Data = Res<'static, SimSettings>;

    /// Follows the settings; true when contacts were turned on or off (the particles are
    /// chosen again).
    fn sync(&mut self, settings: SystemParamItem<Self::Data>) -> bool {
        self.set_culling(settings.0.culling);
        self.set_enabled(settings.0.contacts)
    }
}
