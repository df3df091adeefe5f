//! Joint-space inertia matrix `D(q)` of Eq 16 by the composite rigid body algorithm.
//!
//! Why CRBA instead of six RNEA calls: one inward sweep accumulates the composite inertia of links
//! i..6 once, and each column then only needs the unit-acceleration wrench carried inward, which
//! is several times cheaper and gives an exactly symmetric matrix. Composite inertias are kept as
//! the six distinct entries of a symmetric tensor, rotated with the DH structure (a signed
//! permutation for the twist, then a planar rotation about z) rather than as full 3x3 products.

use nalgebra::{Matrix6, RealField, Vector3};

use super::dh::{DhLink, JointTrig, SinCos, Twist};
use super::model::{BodyInertia, Puma560};

/// Symmetric 3x3 inertia tensor by its six distinct entries.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SymmetricInertia<T> {
    xx: T,
    yy: T,
    zz: T,
    xy: T,
    xz: T,
    yz: T,
}

impl<T: RealField + Copy> SymmetricInertia<T> {
    fn from_body(body: &BodyInertia<T>) -> Self {
        let m = &body.inertia_origin;
        SymmetricInertia {
            xx: m.m11,
            yy: m.m22,
            zz: m.m33,
            xy: m.m12,
            xz: m.m13,
            yz: m.m23,
        }
    }

    fn add(&self, other: &Self) -> Self {
        SymmetricInertia {
            xx: self.xx + other.xx,
            yy: self.yy + other.yy,
            zz: self.zz + other.zz,
            xy: self.xy + other.xy,
            xz: self.xz + other.xz,
            yz: self.yz + other.yz,
        }
    }

    /// `R I R^T` with `R = Rz(q) Rx(alpha)`: the twist permutes and signs the entries, then the
    /// planar rotation mixes the x-y block.
    fn rotated_to_parent(&self, link: &DhLink<T>, trig: &SinCos<T>) -> Self {
        // P I P^T for P = Rx(alpha): +pi/2 maps (x, y, z) -> (x, -z, y); -pi/2 -> (x, z, -y).
        let j = match link.twist {
            Twist::Zero => *self,
            Twist::PlusHalfPi => SymmetricInertia {
                xx: self.xx,
                yy: self.zz,
                zz: self.yy,
                xy: -self.xz,
                xz: self.xy,
                yz: -self.yz,
            },
            Twist::MinusHalfPi => SymmetricInertia {
                xx: self.xx,
                yy: self.zz,
                zz: self.yy,
                xy: self.xz,
                xz: -self.xy,
                yz: -self.yz,
            },
        };
        let (c, s) = (trig.cos, trig.sin);
        let (cc, ss, cs) = (c * c, s * s, c * s);
        let two_cs_xy = (cs + cs) * j.xy;
        SymmetricInertia {
            xx: cc * j.xx - two_cs_xy + ss * j.yy,
            yy: ss * j.xx + two_cs_xy + cc * j.yy,
            zz: j.zz,
            xy: cs * (j.xx - j.yy) + (cc - ss) * j.xy,
            xz: c * j.xz - s * j.yz,
            yz: s * j.xz + c * j.yz,
        }
    }

    /// Moves the reference point by `-p` for a body of mass `m` and first moment `h` about the
    /// old point: `I + 2 (h.p) E - (p h^T + h p^T) + m (|p|^2 E - p p^T)`.
    fn shifted(&self, mass: T, h: &Vector3<T>, p: &Vector3<T>) -> Self {
        let h_dot_p = h.dot(p);
        let diagonal = h_dot_p + h_dot_p + mass * p.norm_squared();
        let mp = p * mass;
        SymmetricInertia {
            xx: self.xx + diagonal - (p.x * h.x + p.x * h.x) - mp.x * p.x,
            yy: self.yy + diagonal - (p.y * h.y + p.y * h.y) - mp.y * p.y,
            zz: self.zz + diagonal - (p.z * h.z + p.z * h.z) - mp.z * p.z,
            xy: self.xy - (p.x * h.y + h.x * p.y) - mp.x * p.y,
            xz: self.xz - (p.x * h.z + h.x * p.z) - mp.x * p.z,
            yz: self.yz - (p.y * h.z + h.y * p.z) - mp.y * p.z,
        }
    }
}

/// Mass, first moment and symmetric inertia of a composite body about a frame origin.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Composite<T> {
    mass: T,
    first_moment: Vector3<T>,
    inertia: SymmetricInertia<T>,
}

impl<T: RealField + Copy> Composite<T> {
    fn from_body(body: &BodyInertia<T>) -> Self {
        Composite {
            mass: body.mass,
            first_moment: body.first_moment,
            inertia: SymmetricInertia::from_body(body),
        }
    }

    fn add(&self, other: &Self) -> Self {
        Composite {
            mass: self.mass + other.mass,
            first_moment: self.first_moment + other.first_moment,
            inertia: self.inertia.add(&other.inertia),
        }
    }

    /// Frame {i} about its origin -> frame {i-1} about its origin: rotate by `R_i`, then shift by
    /// `p = R_i p*_i` (the origin of {i} seen from {i-1}).
    fn expressed_in_parent(
        &self,
        link: &DhLink<T>,
        trig: &SinCos<T>,
        origin_in_child: &Vector3<T>,
    ) -> Self {
        let first_moment = link.to_parent(trig, &self.first_moment);
        let shift = link.to_parent(trig, origin_in_child);
        let inertia =
            self.inertia
                .rotated_to_parent(link, trig)
                .shifted(self.mass, &first_moment, &shift);
        Composite {
            mass: self.mass,
            first_moment: first_moment + shift * self.mass,
            inertia,
        }
    }
}

impl<T: RealField + Copy> Puma560<T> {
    /// Rigid-body joint-space inertia matrix (no armature) from precomputed joint trig.
    pub fn rigid_mass_matrix_with(&self, trig: &JointTrig<T>) -> Matrix6<T> {
        let mut mass_matrix = Matrix6::zeros();
        // Composite of links i+1..6 expressed in frame {i} (0-based link index i).
        let mut outboard: Option<Composite<T>> = None;
        let links = self
            .dh
            .iter()
            .zip(trig.joints.iter())
            .zip(self.origins_in_child.iter())
            .zip(self.bodies.iter())
            .enumerate()
            .rev();
        for (joint, (((link, joint_trig), origin), body)) in links {
            let own = Composite::from_body(body);
            let composite = match outboard {
                Some(outer) => own.add(&outer),
                None => own,
            };
            // Links joint..6 seen from the frame whose z axis through its origin is this joint.
            let in_parent = composite.expressed_in_parent(link, joint_trig, origin);
            outboard = Some(in_parent);
            // Unit acceleration about z: momentum rate (z x h, I_O z).
            let h = in_parent.first_moment;
            let mut force = Vector3::new(-h.y, h.x, T::zero());
            let mut moment = Vector3::new(
                in_parent.inertia.xz,
                in_parent.inertia.yz,
                in_parent.inertia.zz,
            );
            if let Some(entry) = mass_matrix.get_mut((joint, joint)) {
                *entry = moment.z;
            }
            // Carry the wrench inward: frame {j+1} -> {j} is `(R f, R (n + p* x f))`.
            let inner_links = self
                .dh
                .iter()
                .zip(trig.joints.iter())
                .zip(self.origins_in_child.iter())
                .enumerate()
                .take(joint)
                .rev();
            for (inner, ((inner_link, inner_trig), inner_origin)) in inner_links {
                let moment_about_inner = moment + inner_origin.cross(&force);
                force = inner_link.to_parent(inner_trig, &force);
                moment = inner_link.to_parent(inner_trig, &moment_about_inner);
                // Now in the frame whose z axis is joint `inner`'s axis (0-based).
                let value = moment.z;
                if let Some(entry) = mass_matrix.get_mut((joint, inner)) {
                    *entry = value;
                }
                if let Some(entry) = mass_matrix.get_mut((inner, joint)) {
                    *entry = value;
                }
            }
        }
        mass_matrix
    }
}
