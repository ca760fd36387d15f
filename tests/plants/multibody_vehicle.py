"""An independent model of the vehicle in Drake's MultibodyPlant, to cross-check MarineVehicle.

It lives beside its test (``test_marine_vehicle.py``) as that test's independent formulation:
it is not a plant of the closed loop (no ``u1_B``, ``u2_W`` inputs; it cannot hold added mass).

One free rigid body; gravity from the plant's gravity field; 8 ``Propeller`` s for the
thrusters; buoyancy at the centre of buoyancy and the damping ``D(ν) ν`` applied as
``ExternallyAppliedSpatialForce`` s (a world-frame force at a body point), merged with the
propellers' forces by an ``ExternallyAppliedSpatialForceMultiplexer``. Saturation and the
thrust lag are Drake's ``Saturation`` and ``FirstOrderLowPassFilter``.

What this model does *not* hold: added mass. Drake has no hydrodynamics and ``SpatialInertia``
holds one scalar mass, so an anisotropic ``M_A`` cannot live in it. The cross-check therefore
runs both models with ``added_mass`` set to zero; the rigid-body dynamics (including the
Coriolis terms of a centre of gravity away from the body origin), the kinematics, the thrust
map, the restoring forces and the damping are then each computed by different code.
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce, SpatialVelocity
from pydrake.multibody.plant import (
    ExternallyAppliedSpatialForce,
    ExternallyAppliedSpatialForceMultiplexer,
    MultibodyPlant,
    Propeller,
    PropellerInfo,
)
from pydrake.multibody.tree import BodyIndex, RotationalInertia, SpatialInertia
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import FirstOrderLowPassFilter, Saturation

from drake_uuv.scenario.plants import HoveringAuv

__all__ = ["HydrostaticsAndDamping", "MultibodyVehicle"]


class HydrostaticsAndDamping(LeafSystem):
    """Buoyancy and ``D(ν) ν`` on one MultibodyPlant body, as externally applied forces.

    The buoyancy ``B e_z`` (world up) acts at the centre of buoyancy. The damping is written
    here from its definition, independently of ``drake_uuv/models/marine_vehicle.py``: with
    the body velocity ``ν = [R_WBᵀ v_WBo, R_WBᵀ ω_WB]``, the body-frame force and moment
    about the body origin are ``−(D_lin + D_quad |ν|) ν`` (element-wise), rotated to the
    world and applied at the body origin.

    .. pydrake_system::

        name: HydrostaticsAndDamping
        input_ports:
        - body_poses
        - body_spatial_velocities
        output_ports:
        - spatial_forces
    """

    def __init__(self, body_index: BodyIndex, config: HoveringAuv) -> None:
        super().__init__()
        self._body_index = body_index
        self._list_index = int(body_index)
        self._buoyancy = config.buoyant_force
        self._r_BB = np.asarray(config.center_of_buoyancy, dtype=float)
        self._linear = np.asarray(config.linear_damping, dtype=float)
        self._quadratic = np.asarray(config.quadratic_damping, dtype=float)
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self._velocities = self.DeclareAbstractInputPort(
            "body_spatial_velocities", AbstractValue.Make([SpatialVelocity()])
        )
        self.DeclareAbstractOutputPort(
            "spatial_forces",
            lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
            self._calc,
        )

    def _calc(self, context: Context, output: AbstractValue) -> None:
        X_WB = self._poses.Eval(context)[self._list_index]
        V_WB = self._velocities.Eval(context)[self._list_index]
        R_WB = X_WB.rotation().matrix()
        nu = np.concatenate([R_WB.T @ V_WB.translational(), R_WB.T @ V_WB.rotational()])
        damping_B = -(self._linear + self._quadratic * np.abs(nu)) * nu
        damping = ExternallyAppliedSpatialForce()
        damping.body_index = self._body_index
        damping.p_BoBq_B = np.zeros(3)
        damping.F_Bq_W = SpatialForce(tau=R_WB @ damping_B[3:], f=R_WB @ damping_B[:3])
        buoyancy = ExternallyAppliedSpatialForce()
        buoyancy.body_index = self._body_index
        buoyancy.p_BoBq_B = self._r_BB
        buoyancy.F_Bq_W = SpatialForce(tau=np.zeros(3), f=np.array([0.0, 0.0, self._buoyancy]))
        output.set_value([damping, buoyancy])


class MultibodyVehicle(Diagram):
    """The vehicle as a MultibodyPlant (``plant``), for cross-checks (see the module notes).

    ``config.added_mass`` must be zero. Input ``thrust_command`` (n) [N]; output ``state``
    (13), the plant's ``[q_WB (w, x, y, z), p_WU, ω_WB (world), v_WU (world)]``. Read
    ``pose`` and ``spatial_velocity`` for the body's values in a root context.
    """

    def __init__(self, config: HoveringAuv) -> None:
        super().__init__()
        config.validate("config")
        if np.any(np.asarray(config.added_mass) != 0.0):
            raise ValueError(
                "config.added_mass: must be zero, MultibodyPlant's SpatialInertia holds one "
                f"scalar mass, got {config.added_mass!r}"
            )
        builder = DiagramBuilder()
        plant = builder.AddNamedSystem("plant", MultibodyPlant(time_step=0.0))
        inertia = np.asarray(config.inertia, dtype=float)
        body = plant.AddRigidBody(
            "hull",
            SpatialInertia.MakeFromCentralInertia(
                config.mass,
                np.asarray(config.center_of_gravity, dtype=float),
                RotationalInertia(
                    inertia[0, 0],
                    inertia[1, 1],
                    inertia[2, 2],
                    inertia[0, 1],
                    inertia[0, 2],
                    inertia[1, 2],
                ),
            ),
        )
        plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -config.gravity])
        plant.Finalize()
        # Propeller frame P: origin at the thruster, z along its thrust direction.
        infos = []
        for position, direction in zip(
            config.thruster_positions, config.thruster_directions, strict=True
        ):
            R_BP = RotationMatrix.MakeFromOneVector(np.asarray(direction, dtype=float), 2)
            infos.append(
                PropellerInfo(body.index(), RigidTransform(R_BP, np.asarray(position)), 1.0, 0.0)
            )
        propellers = builder.AddNamedSystem("propellers", Propeller(infos))
        n = len(infos)
        saturation = builder.AddNamedSystem(
            "saturation",
            Saturation(-config.max_thrust * np.ones(n), config.max_thrust * np.ones(n)),
        )
        if config.thrust_time_constant > 0.0:
            lag = builder.AddNamedSystem(
                "thrust_lag", FirstOrderLowPassFilter(config.thrust_time_constant, n)
            )
            builder.Connect(saturation.get_output_port(), lag.get_input_port())
            builder.Connect(lag.get_output_port(), propellers.get_command_input_port())
        else:
            builder.Connect(saturation.get_output_port(), propellers.get_command_input_port())
        hydro = builder.AddNamedSystem(
            "hydrostatics_and_damping", HydrostaticsAndDamping(body.index(), config)
        )
        builder.Connect(plant.get_body_poses_output_port(), propellers.get_body_poses_input_port())
        builder.Connect(plant.get_body_poses_output_port(), hydro.GetInputPort("body_poses"))
        builder.Connect(
            plant.get_body_spatial_velocities_output_port(),
            hydro.GetInputPort("body_spatial_velocities"),
        )
        mux = builder.AddNamedSystem("forces", ExternallyAppliedSpatialForceMultiplexer(2))
        builder.Connect(propellers.get_spatial_forces_output_port(), mux.get_input_port(0))
        builder.Connect(hydro.get_output_port(), mux.get_input_port(1))
        builder.Connect(mux.get_output_port(), plant.get_applied_spatial_force_input_port())
        builder.ExportInput(saturation.get_input_port(), "thrust_command")
        builder.ExportOutput(plant.get_state_output_port(), "state")
        builder.BuildInto(self)
        self._plant, self._body = plant, body

    @property
    def plant(self) -> MultibodyPlant:
        return self._plant

    def set_initial_state(
        self,
        root_context: Context,
        p_WU: np.ndarray,
        R_WB: np.ndarray,
        v_WU: np.ndarray,
        w_WB: np.ndarray,
    ) -> None:
        """Sets the body's pose and spatial velocity (world frame) in ``root_context``."""
        plant_context = self._plant.GetMyMutableContextFromRoot(root_context)
        self._plant.SetFreeBodyPose(
            plant_context, self._body, RigidTransform(RotationMatrix(R_WB), p_WU)
        )
        self._plant.SetFreeBodySpatialVelocity(
            plant_context, self._body, SpatialVelocity(w=w_WB, v=v_WU)
        )

    def pose(self, root_context: Context) -> RigidTransform:
        """``X_WB``, the body's pose in the world."""
        plant_context = self._plant.GetMyContextFromRoot(root_context)
        return self._plant.EvalBodyPoseInWorld(plant_context, self._body)

    def spatial_velocity(self, root_context: Context) -> SpatialVelocity:
        """``V_WB``: the body origin's velocity and the angular velocity, world frame."""
        plant_context = self._plant.GetMyContextFromRoot(root_context)
        return self._plant.EvalBodySpatialVelocityInWorld(plant_context, self._body)
