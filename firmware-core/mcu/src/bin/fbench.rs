#![no_std]
#![no_main]
use cortex_m_rt::entry;
#[entry]
fn main() -> ! { firmware_mcu::calibrate(4); firmware_mcu::exit(true) }
