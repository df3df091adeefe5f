//! Onlookers of a pick: what the runner shows of each period to whatever
//! draws or logs it (the pick's own log, the camera recordings, the Rerun
//! recording), without changing the run. A watcher gets the world (truth) and
//! what crossed the link; nothing it does flows back into the controller.

use anyhow::Result;
use shared::protocol::{ActuatorCommand, CameraFeatureFrame, PickTelemetry};

use crate::world::{World, WorldTruth};

/// What a pick shows an onlooker. Only [`PickWatcher::period`] is required.
pub trait PickWatcher {
    /// Every control period: the world and the controller's command just
    /// before the world applies it (a frame triggered by that command is
    /// exposed at this instant).
    fn period(&mut self, world: &World, command: &ActuatorCommand) -> Result<()>;

    /// The camera frames the controller is sent now (before this period's
    /// sensor sample), exactly as sent.
    fn frames_sent(&mut self, _world: &World, _frames: &[CameraFeatureFrame]) -> Result<()> {
        Ok(())
    }

    /// A telemetry message from the controller with the truth at its own
    /// instant (the message comes a period or more after it).
    fn telemetry(&mut self, _telemetry: &PickTelemetry, _truth: &WorldTruth) -> Result<()> {
        Ok(())
    }
}

/// A watcher that looks at nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoWatcher;

impl PickWatcher for NoWatcher {
    fn period(&mut self, _: &World, _: &ActuatorCommand) -> Result<()> {
        Ok(())
    }
}

/// A closure shown every period (and nothing else).
pub struct EachPeriod<'a>(pub &'a mut dyn FnMut(&World, &ActuatorCommand) -> Result<()>);

impl PickWatcher for EachPeriod<'_> {
    fn period(&mut self, world: &World, command: &ActuatorCommand) -> Result<()> {
        (self.0)(world, command)
    }
}

/// Two watchers shown the same run, the first first.
pub struct Both<'a, 'b>(pub &'a mut dyn PickWatcher, pub &'b mut dyn PickWatcher);

impl PickWatcher for Both<'_, '_> {
    fn period(&mut self, world: &World, command: &ActuatorCommand) -> Result<()> {
        self.0.period(world, command)?;
        self.1.period(world, command)
    }

    fn frames_sent(&mut self, world: &World, frames: &[CameraFeatureFrame]) -> Result<()> {
        self.0.frames_sent(world, frames)?;
        self.1.frames_sent(world, frames)
    }

    fn telemetry(&mut self, telemetry: &PickTelemetry, truth: &WorldTruth) -> Result<()> {
        self.0.telemetry(telemetry, truth)?;
        self.1.telemetry(telemetry, truth)
    }
}
