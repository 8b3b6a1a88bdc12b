//! Patches and the edge-to-edge form factors F (docs/transport.md#form-factors).
//!
//! Each edge is cut into equal patches no longer than the patch length. Row
//! `i` of F is the mean, over Gauss-Legendre points `x` on patch `i`, of the
//! exact point-to-patch factors `K(x, j) = 1/2 * integral of cos(theta_x) w d psi`
//! over the part of patch `j` that `x` sees ([`crate::visibility`] finds the
//! visible parts, [`crate::transport::kernel`] integrates them in closed form). Because
//! every point's factors integrate exactly over the directions it sees, a row
//! of F sums to exactly the visible fraction of the half-plane (1 in a closed
//! room) whatever the quadrature.
//!
//! Reciprocity `L_i F_ij = L_j F_ji` holds only up to quadrature error for
//! the raw rows, so flatbake stores the symmetric average
//! `S_ij = (L_i F_ij + L_j F_ji) / 2` and defines `F = D^-1 S` with the
//! "effective lengths" `D_i = sum_j S_ij / t_i`, where `t_i` is the raw row
//! sum. Then rows still sum to `t_i` exactly, `D F` is symmetric, and
//! `D / rho - S` is symmetric positive definite: the solve can use Cholesky
//! or conjugate gradients, and energy balances exactly in the discrete system.
//! `D_i` differs from the true length `L_i` only by quadrature error.

mod factors;
pub mod kernel;
pub mod moments;
pub mod paper;
mod patches;
pub mod solve;

pub use factors::{
    FormFactors, SlopeRows, estimate_entries, form_factors, point_factors, wanted_reach,
};
pub use patches::{Patches, axis_vec, clearance, normal_vec};
