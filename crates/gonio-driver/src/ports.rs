//! The serial ports this machine has, and ports named by USB serial number.
//!
//! `/dev/ttyUSB0` names whichever adapter enumerated first, and the order changes when
//! adapters are replugged or the machine reboots. A port written `usb:SERIAL` names
//! the USB serial device whose serial number is `SERIAL` (an FTDI adapter's, or a
//! Thorlabs K-Cube's, which is its own USB device), wherever it enumerated; it is
//! looked up again at every reconnection.

/// The prefix of a port named by USB serial number.
pub const USB_PREFIX: &str = "usb:";

/// What the operating system says of a USB serial device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UsbInfo {
    /// Vendor id.
    pub vid: u16,
    /// Product id.
    pub pid: u16,
    /// Serial number, if the device has one.
    pub serial_number: Option<String>,
    /// Manufacturer string.
    pub manufacturer: Option<String>,
    /// Product string.
    pub product: Option<String>,
}

/// One serial port.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PortInfo {
    /// Its path (`/dev/ttyUSB0`).
    pub path: String,
    /// Its USB identity, for USB devices.
    pub usb: Option<UsbInfo>,
    /// `usb`, `pci`, `bluetooth` or `unknown`, as the OS reports it.
    pub bus: &'static str,
}

/// The serial ports the OS lists (on Linux from sysfs), sorted by path.
pub fn list() -> Result<Vec<PortInfo>, String> {
    let mut ports: Vec<PortInfo> = serialport::available_ports()
        .map_err(|e| format!("listing serial ports: {e}"))?
        .into_iter()
        .map(|p| {
            let (usb, bus) = match p.port_type {
                serialport::SerialPortType::UsbPort(u) => (
                    Some(UsbInfo {
                        vid: u.vid,
                        pid: u.pid,
                        serial_number: u.serial_number,
                        manufacturer: u.manufacturer,
                        product: u.product,
                    }),
                    "usb",
                ),
                serialport::SerialPortType::PciPort => (None, "pci"),
                serialport::SerialPortType::BluetoothPort => (None, "bluetooth"),
                serialport::SerialPortType::Unknown => (None, "unknown"),
            };
            PortInfo {
                path: p.port_name,
                usb,
                bus,
            }
        })
        .collect();
    ports.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(ports)
}

/// The path to open for a configured port name: a path as is, `usb:SERIAL` looked up
/// among the ports the OS lists now.
pub fn resolve(name: &str) -> Result<String, String> {
    if !name.starts_with(USB_PREFIX) {
        return Ok(name.to_string());
    }
    resolve_in(name, &list()?)
}

/// [`resolve`] among given ports.
pub fn resolve_in(name: &str, ports: &[PortInfo]) -> Result<String, String> {
    let Some(serial) = name.strip_prefix(USB_PREFIX) else {
        return Ok(name.to_string());
    };
    let matching: Vec<&PortInfo> = ports
        .iter()
        .filter(|p| {
            p.usb
                .as_ref()
                .and_then(|u| u.serial_number.as_deref())
                .is_some_and(|s| s == serial)
        })
        .collect();
    match matching.as_slice() {
        [one] => Ok(one.path.clone()),
        [] => {
            let known: Vec<&str> = ports
                .iter()
                .filter_map(|p| p.usb.as_ref()?.serial_number.as_deref())
                .collect();
            Err(if known.is_empty() {
                format!("no USB serial device with serial number {serial:?} (none is connected)")
            } else {
                format!(
                    "no USB serial device with serial number {serial:?} (connected: {})",
                    known.join(", ")
                )
            })
        }
        many => Err(format!(
            "serial number {serial:?} is shared by {}; name the port by path",
            many.iter()
                .map(|p| p.path.as_str())
                .collect::<Vec<_>>()
                .join(" and ")
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn usb(path: &str, serial: Option<&str>) -> PortInfo {
        PortInfo {
            path: path.into(),
            usb: Some(UsbInfo {
                vid: 0x0403,
                pid: 0xfaf0,
                serial_number: serial.map(str::to_string),
                manufacturer: Some("Thorlabs".into()),
                product: Some("Kinesis K-Cube  DC Driver".into()),
            }),
            bus: "usb",
        }
    }

    #[test]
    fn paths_pass_through_and_serials_resolve() {
        let ports = [
            usb("/dev/ttyUSB0", Some("27000001")),
            usb("/dev/ttyUSB1", Some("55000123")),
            usb("/dev/ttyUSB2", None),
        ];
        assert_eq!(
            resolve_in("/dev/ttyS0", &ports).as_deref(),
            Ok("/dev/ttyS0")
        );
        assert_eq!(
            resolve_in("usb:55000123", &ports).as_deref(),
            Ok("/dev/ttyUSB1")
        );
        let e = resolve_in("usb:999", &ports).unwrap_err();
        assert!(
            e.contains("\"999\"") && e.contains("27000001, 55000123"),
            "{e}"
        );
        assert!(
            resolve_in("usb:1", &[])
                .unwrap_err()
                .contains("none is connected")
        );
    }

    #[test]
    fn a_shared_serial_number_is_refused() {
        let ports = [
            usb("/dev/ttyUSB0", Some("A")),
            usb("/dev/ttyUSB3", Some("A")),
        ];
        let e = resolve_in("usb:A", &ports).unwrap_err();
        assert!(e.contains("/dev/ttyUSB0 and /dev/ttyUSB3"), "{e}");
    }
}
