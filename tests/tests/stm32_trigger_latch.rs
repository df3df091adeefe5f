//! The STM32F407 board's camera-trigger latch (`firmware/src/board/stm32f407/
//! latch.rs`, only `core`), built for the host so that its unit tests run
//! with the workspace's: the trigger line rises first, then every counter
//! is read, with nothing else in between.
#[path = "../../firmware/src/board/stm32f407/latch.rs"]
mod latch;
