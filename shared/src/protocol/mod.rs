//! Serial protocol v1 between the vision computer / simulator and the controller.
