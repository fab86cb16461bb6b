//! `brdf-rig ports`: list the serial ports the system knows, to find the rig's path for a
//! profile's `[serial] port`.

use std::process::ExitCode;

use anyhow::Context;

pub fn run() -> anyhow::Result<ExitCode> {
    let ports = serialport::available_ports().context("listing serial ports")?;
    if ports.is_empty() {
        outln!("no serial ports found (the simulated rig needs none: use the default profile)");
    }
    for p in ports {
        let kind = match p.port_type {
            serialport::SerialPortType::UsbPort(u) => format!(
                "USB {:04x}:{:04x} {} {}",
                u.vid,
                u.pid,
                u.manufacturer.unwrap_or_default(),
                u.product.unwrap_or_default()
            ),
            serialport::SerialPortType::PciPort => "PCI".into(),
            serialport::SerialPortType::BluetoothPort => "Bluetooth".into(),
            serialport::SerialPortType::Unknown => "unknown".into(),
        };
        outln!("{}\t{}", p.port_name, kind.trim());
    }
    Ok(ExitCode::SUCCESS)
}
