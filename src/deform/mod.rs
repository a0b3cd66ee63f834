//! Handle deformation (SPEC §6.3–6.4): a body posed by handles — points and affine
//! regions — through the linear subspace of Wang et al. 2015 (`V = W H`, with `W`
//! from the linearly precise smoothness energy of [`smoothness`]), as rigid as possible
//! (Sorkine & Alexa 2007, [`arap`]), or by non-linear solves reduced to the subspace
//! ([`reduced`]). The handles and their keyframes are in [`handles`] and [`keys`].
//! Plain data on a body's lattice; the ECS component that poses a body each frame is
//! [`crate::ecs::handles::HandlePose`].

pub mod arap;
pub mod handles;
pub mod keys;
pub mod reduced;
pub mod smoothness;
pub mod weights;
