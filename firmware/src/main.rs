//! Workcell controller firmware (placeholder until the board bring-up lands).
#![no_std]
#![no_main]
