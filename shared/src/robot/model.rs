//! The [`Puma560`] model: parameter storage, builders and scalar casting.
//!
//! Eq 16 of the paper, `tau = D(q) qdd + C(q, qd) + G(q)`, needs one consistent set of inertial
//! parameters in every algorithm. The table is stored once (as given: mass, COM, inertia about the
//! COM), and each builder re-derives the per-link quantities the recursions use (mass, first
//! moment and inertia about the frame origin), so the variants (payload, mass mismatch, friction
//! scale) cannot drift apart between RNEA and CRBA.

use nalgebra::{Matrix3, RealField, Vector3};

use super::dh::DhLink;
use super::error::RobotError;
use super::table;
use super::JointVector;

/// Which non-rigid terms the model includes (both off = the reference vectors' model).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriveOptions {
    /// Motor armature inertia `G^2 Jm` on the diagonal of `M` (and in `tau` as `G^2 Jm qdd`).
    pub armature: bool,
    /// Joint friction `G^2 B qd + |G| Tc(qd)` in `tau`.
    pub friction: bool,
}

/// Rigid-body parameters of one link as the table gives them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkInertial<T> {
    /// Mass (kg).
    pub mass: T,
    /// Centre of mass in frame {j}, relative to its origin (m).
    pub com: Vector3<T>,
    /// Inertia tensor about the COM, axes parallel to frame {j} (kg m^2).
    pub inertia_com: Matrix3<T>,
}

/// Motor-side drive parameters of one joint (the table's Jm, G, B, Tc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveParams<T> {
    /// Gear ratio `G` (signed).
    pub gear_ratio: T,
    /// Motor armature inertia `Jm` (kg m^2).
    pub motor_inertia: T,
    /// Viscous friction `B` (N m s/rad).
    pub viscous: T,
    /// Coulomb friction for `qd > 0` (N m).
    pub coulomb_positive: T,
    /// Coulomb friction for `qd < 0` (N m) (negative).
    pub coulomb_negative: T,
}

/// A point mass fixed in the flange frame {6}.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Payload<T> {
    /// Mass (kg).
    pub mass: T,
    /// Position in frame {6} (m).
    pub com_flange: Vector3<T>,
}

/// Joint limits: position from the table; velocity (Corke 1996) and torque (AKB86): see [`table`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits<T> {
    /// Lower position limit (rad).
    pub position_min: JointVector<T>,
    /// Upper position limit (rad).
    pub position_max: JointVector<T>,
    /// Symmetric speed limit `|qd| <= velocity_max` (rad/s).
    pub velocity_max: JointVector<T>,
    /// Symmetric torque limit `|tau| <= torque_max` (N m).
    pub torque_max: JointVector<T>,
}

/// Mass, first moment `h = m c` and inertia about the frame origin of one body, in its link
/// frame: the form in which the Newton-Euler equations about a frame origin are linear in the
/// parameters, so a payload or a mass scale is a plain sum or product.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyInertia<T> {
    /// Mass (kg).
    pub mass: T,
    /// First moment of mass `m c` about the frame origin (kg m).
    pub first_moment: Vector3<T>,
    /// Inertia about the frame origin (kg m^2).
    pub inertia_origin: Matrix3<T>,
}

impl<T: RealField + Copy> BodyInertia<T> {
    /// A point or body of mass `m` with COM `c` and COM inertia `i_com`, by the parallel-axis
    /// theorem `I_O = I_C + m (|c|^2 E - c c^T)`.
    pub fn from_com(mass: T, com: &Vector3<T>, inertia_com: &Matrix3<T>) -> Self {
        let shift = (Matrix3::identity() * com.norm_squared() - com * com.transpose()) * mass;
        BodyInertia {
            mass,
            first_moment: com * mass,
            inertia_origin: inertia_com + shift,
        }
    }
}

/// Drive terms referred to the joint side, precomputed for the hot paths.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct JointDrive<T> {
    /// `G^2 Jm` (kg m^2).
    pub armature: T,
    /// `G^2 B` times the friction scale (N m s/rad).
    pub viscous: T,
    /// `|G| Tc+` times the friction scale (N m).
    pub coulomb_positive: T,
    /// `|G| Tc-` times the friction scale (N m).
    pub coulomb_negative: T,
}

/// The PUMA 560 arm: kinematics and dynamics (paper Eq 16), generic over the scalar so the f64
/// plant and the f32 controller share one implementation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Puma560<T: RealField + Copy> {
    pub(crate) dh: [DhLink<T>; 6],
    /// `p*_i` per link (see [`DhLink::origin_in_child`]).
    pub(crate) origins_in_child: [Vector3<T>; 6],
    links: [LinkInertial<T>; 6],
    drives: [DriveParams<T>; 6],
    limits: JointLimits<T>,
    pub(crate) options: DriveOptions,
    payload: Option<Payload<T>>,
    link_mass_scale: [T; 6],
    friction_scale: T,
    /// `None`: Coulomb term switches sign at `qd = 0` (0 exactly there). `Some(w)`: `tanh(qd / w)`.
    pub(crate) coulomb_smoothing: Option<T>,
    pub(crate) gravity: Vector3<T>,
    /// Derived: effective per-link inertia (scaled, payload merged into link 6).
    pub(crate) bodies: [BodyInertia<T>; 6],
    /// Derived: joint-side drive terms.
    pub(crate) joint_drives: [JointDrive<T>; 6],
}

fn real<T: RealField + Copy>(value: f64) -> T {
    nalgebra::convert(value)
}

fn real_vector<T: RealField + Copy>(values: &[f64; 6]) -> JointVector<T> {
    JointVector::from(values.map(real::<T>))
}

fn cast_scalar<T: RealField + Copy, U: RealField + Copy>(value: T) -> U {
    // f32 <-> f64 (the supported scalars) convert by `as`; nothing here can fail or panic.
    let as_f64: f64 = value.to_subset_unchecked();
    nalgebra::convert(as_f64)
}

fn cast_vector3<T: RealField + Copy, U: RealField + Copy>(v: &Vector3<T>) -> Vector3<U> {
    v.map(cast_scalar::<T, U>)
}

fn is_valid_non_negative<T: RealField + Copy>(value: T) -> bool {
    value.is_finite() && value >= T::zero()
}

impl<T: RealField + Copy> Default for Puma560<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: RealField + Copy> Puma560<T> {
    /// The rigid-body table of `docs/reference/puma560-model.md`: no armature, no friction, no payload,
    /// gravity `[0, 0, -9.81]`.
    pub fn new() -> Self {
        let dh = table::DH_ROWS.map(|(a, d, twist)| DhLink {
            a: real(a),
            d: real(d),
            twist,
        });
        let links = core::array::from_fn(|j| {
            let mass = table::MASS.get(j).copied().unwrap_or(0.0);
            let com = table::COM.get(j).copied().unwrap_or([0.0; 3]);
            let [ixx, iyy, izz] = table::INERTIA_DIAGONAL.get(j).copied().unwrap_or([0.0; 3]);
            LinkInertial {
                mass: real(mass),
                com: Vector3::from(com.map(real::<T>)),
                inertia_com: Matrix3::from_diagonal(&Vector3::new(real(ixx), real(iyy), real(izz))),
            }
        });
        let drives = core::array::from_fn(|j| {
            let pick = |values: &[f64; 6]| real::<T>(values.get(j).copied().unwrap_or(0.0));
            DriveParams {
                gear_ratio: pick(&table::GEAR_RATIO),
                motor_inertia: pick(&table::MOTOR_INERTIA),
                viscous: pick(&table::VISCOUS_FRICTION),
                coulomb_positive: pick(&table::COULOMB_POSITIVE),
                coulomb_negative: pick(&table::COULOMB_NEGATIVE),
            }
        });
        let limits = JointLimits {
            position_min: real_vector(&table::POSITION_MIN),
            position_max: real_vector(&table::POSITION_MAX),
            velocity_max: real_vector(&table::VELOCITY_MAX),
            torque_max: real_vector(&table::TORQUE_MAX),
        };
        let [gx, gy, gz] = table::GRAVITY;
        Self::assemble(
            dh,
            links,
            drives,
            limits,
            DriveOptions::default(),
            None,
            [T::one(); 6],
            T::one(),
            None,
            Vector3::new(real(gx), real(gy), real(gz)),
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn assemble(
        dh: [DhLink<T>; 6],
        links: [LinkInertial<T>; 6],
        drives: [DriveParams<T>; 6],
        limits: JointLimits<T>,
        options: DriveOptions,
        payload: Option<Payload<T>>,
        link_mass_scale: [T; 6],
        friction_scale: T,
        coulomb_smoothing: Option<T>,
        gravity: Vector3<T>,
    ) -> Self {
        let mut model = Puma560 {
            dh,
            origins_in_child: dh.map(|link| link.origin_in_child()),
            links,
            drives,
            limits,
            options,
            payload,
            link_mass_scale,
            friction_scale,
            coulomb_smoothing,
            gravity,
            bodies: [BodyInertia {
                mass: T::zero(),
                first_moment: Vector3::zeros(),
                inertia_origin: Matrix3::zeros(),
            }; 6],
            joint_drives: [JointDrive {
                armature: T::zero(),
                viscous: T::zero(),
                coulomb_positive: T::zero(),
                coulomb_negative: T::zero(),
            }; 6],
        };
        model.derive();
        model
    }

    /// Recomputes the derived per-link inertias and joint-side drive terms from the table,
    /// the scales and the payload.
    fn derive(&mut self) {
        for ((body, link), scale) in self
            .bodies
            .iter_mut()
            .zip(self.links.iter())
            .zip(self.link_mass_scale.iter())
        {
            *body =
                BodyInertia::from_com(link.mass * *scale, &link.com, &(link.inertia_com * *scale));
        }
        if let (Some(payload), Some(flange_body)) = (self.payload, self.bodies.last_mut()) {
            let point = BodyInertia::from_com(payload.mass, &payload.com_flange, &Matrix3::zeros());
            flange_body.mass += point.mass;
            flange_body.first_moment += point.first_moment;
            flange_body.inertia_origin += point.inertia_origin;
        }
        for (joint, drive) in self.joint_drives.iter_mut().zip(self.drives.iter()) {
            let gear_abs = drive.gear_ratio.abs();
            let gear_squared = drive.gear_ratio * drive.gear_ratio;
            *joint = JointDrive {
                armature: gear_squared * drive.motor_inertia,
                viscous: gear_squared * drive.viscous * self.friction_scale,
                coulomb_positive: gear_abs * drive.coulomb_positive * self.friction_scale,
                coulomb_negative: gear_abs * drive.coulomb_negative * self.friction_scale,
            };
        }
    }

    /// Turns the armature and friction terms on or off.
    pub fn with_drive(mut self, options: DriveOptions) -> Self {
        self.options = options;
        self
    }

    /// Adds a point mass fixed in frame {6}. Non-finite or negative input leaves the model
    /// unchanged; use [`Self::try_with_payload`] to get the error instead.
    pub fn with_payload(self, mass_kg: T, com_flange_m: Vector3<T>) -> Self {
        self.try_with_payload(mass_kg, com_flange_m).unwrap_or(self)
    }

    /// Adds (replaces) a point-mass payload fixed in frame {6}.
    pub fn try_with_payload(
        mut self,
        mass_kg: T,
        com_flange_m: Vector3<T>,
    ) -> Result<Self, RobotError> {
        if !is_valid_non_negative(mass_kg) {
            return Err(RobotError::InvalidParameter {
                parameter: "payload mass",
            });
        }
        if !com_flange_m.iter().all(|c| c.is_finite()) {
            return Err(RobotError::InvalidParameter {
                parameter: "payload centre of mass",
            });
        }
        self.payload = Some(Payload {
            mass: mass_kg,
            com_flange: com_flange_m,
        });
        self.derive();
        Ok(self)
    }

    /// Scales link j's mass and inertia by `scale[j]` (model mismatch between plant and
    /// controller). Invalid scales leave the model unchanged; see [`Self::try_with_link_mass_scale`].
    pub fn with_link_mass_scale(self, scale: [T; 6]) -> Self {
        self.try_with_link_mass_scale(scale).unwrap_or(self)
    }

    /// Scales link j's mass and inertia by `scale[j]` (finite, non-negative).
    pub fn try_with_link_mass_scale(mut self, scale: [T; 6]) -> Result<Self, RobotError> {
        if !scale.iter().all(|s| is_valid_non_negative(*s)) {
            return Err(RobotError::InvalidParameter {
                parameter: "link mass scale",
            });
        }
        self.link_mass_scale = scale;
        self.derive();
        Ok(self)
    }

    /// Scales B and Tc of every joint (the controller's imperfect friction knowledge).
    /// An invalid scale leaves the model unchanged; see [`Self::try_with_friction_scale`].
    pub fn with_friction_scale(self, scale: T) -> Self {
        self.try_with_friction_scale(scale).unwrap_or(self)
    }

    /// Scales B and Tc of every joint (finite, non-negative).
    pub fn try_with_friction_scale(mut self, scale: T) -> Result<Self, RobotError> {
        if !is_valid_non_negative(scale) {
            return Err(RobotError::InvalidParameter {
                parameter: "friction scale",
            });
        }
        self.friction_scale = scale;
        self.derive();
        Ok(self)
    }

    /// Replaces the discontinuous Coulomb term by `Tc * tanh(qd / width)` (width in rad/s, e.g.
    /// 0.01 for the simulator): a stiff but smooth law an explicit integrator can step through.
    /// A non-finite or non-positive width is rejected.
    pub fn try_with_coulomb_smoothing(mut self, width: T) -> Result<Self, RobotError> {
        if !(width.is_finite() && width > T::zero()) {
            return Err(RobotError::InvalidParameter {
                parameter: "Coulomb smoothing width",
            });
        }
        self.coulomb_smoothing = Some(width);
        Ok(self)
    }

    /// Replaces the gravity vector (base frame, m/s^2), e.g. zero for energy checks.
    pub fn try_with_gravity(mut self, gravity: Vector3<T>) -> Result<Self, RobotError> {
        if !gravity.iter().all(|g| g.is_finite()) {
            return Err(RobotError::InvalidParameter {
                parameter: "gravity",
            });
        }
        self.gravity = gravity;
        Ok(self)
    }

    /// The same model in another scalar type (e.g. the f64 table to the f32 controller).
    pub fn cast<U: RealField + Copy>(&self) -> Puma560<U> {
        let dh = self.dh.map(|link| DhLink {
            a: cast_scalar(link.a),
            d: cast_scalar(link.d),
            twist: link.twist,
        });
        let links = self.links.map(|link| LinkInertial {
            mass: cast_scalar(link.mass),
            com: cast_vector3(&link.com),
            inertia_com: link.inertia_com.map(cast_scalar::<T, U>),
        });
        let drives = self.drives.map(|drive| DriveParams {
            gear_ratio: cast_scalar(drive.gear_ratio),
            motor_inertia: cast_scalar(drive.motor_inertia),
            viscous: cast_scalar(drive.viscous),
            coulomb_positive: cast_scalar(drive.coulomb_positive),
            coulomb_negative: cast_scalar(drive.coulomb_negative),
        });
        let limits = JointLimits {
            position_min: self.limits.position_min.map(cast_scalar::<T, U>),
            position_max: self.limits.position_max.map(cast_scalar::<T, U>),
            velocity_max: self.limits.velocity_max.map(cast_scalar::<T, U>),
            torque_max: self.limits.torque_max.map(cast_scalar::<T, U>),
        };
        let payload = self.payload.map(|p| Payload {
            mass: cast_scalar(p.mass),
            com_flange: cast_vector3(&p.com_flange),
        });
        Puma560::assemble(
            dh,
            links,
            drives,
            limits,
            self.options,
            payload,
            self.link_mass_scale.map(cast_scalar::<T, U>),
            cast_scalar(self.friction_scale),
            self.coulomb_smoothing.map(cast_scalar::<T, U>),
            cast_vector3(&self.gravity),
        )
    }

    /// Position (table), velocity (Corke 1996, Table 2.21) and torque (AKB86, Table 7) limits.
    pub fn joint_limits(&self) -> &JointLimits<T> {
        &self.limits
    }

    /// The standard DH table in use.
    pub fn dh_table(&self) -> &[DhLink<T>; 6] {
        &self.dh
    }

    /// The rigid-body table (before scaling and payload).
    pub fn link_inertials(&self) -> &[LinkInertial<T>; 6] {
        &self.links
    }

    /// The motor-side drive parameters.
    pub fn drive_params(&self) -> &[DriveParams<T>; 6] {
        &self.drives
    }

    /// The effective per-link inertias the algorithms use (scales and payload applied).
    pub fn body_inertias(&self) -> &[BodyInertia<T>; 6] {
        &self.bodies
    }

    /// Which drive terms are on.
    pub fn drive_options(&self) -> DriveOptions {
        self.options
    }

    /// Gravity in the base frame (m/s^2).
    pub fn gravity(&self) -> &Vector3<T> {
        &self.gravity
    }
}
