//! The LightCrafter's USB HID interface through rusb (system libusb), feature `lightcrafter`.
//!
//! Opens 0451:6401, detaches the kernel's HID driver from interface 0 (Linux binds usbhid to it,
//! which would otherwise own the endpoints), claims it, and moves reports over its interrupt IN
//! and OUT endpoints, found from the configuration descriptor. A libusb context of our own
//! (`Context::new`) turns a missing USB subsystem into an error instead of a panic.

use super::protocol::REPORT_LEN;
use super::{HidTransport, LightcrafterError, PRODUCT_ID, VENDOR_ID};
use rusb::{Context, DeviceHandle, Direction, TransferType, UsbContext};
use std::time::Duration;

/// How long one report may take each way.
const TIMEOUT: Duration = Duration::from_millis(1000);

/// An opened, claimed LightCrafter HID interface.
pub struct UsbTransport {
    handle: DeviceHandle<Context>,
    interface: u8,
    endpoint_in: u8,
    endpoint_out: u8,
}

fn usb_error(e: rusb::Error) -> LightcrafterError {
    match e {
        rusb::Error::NoDevice => LightcrafterError::Unplugged,
        rusb::Error::Access => LightcrafterError::Permission,
        rusb::Error::NotFound => LightcrafterError::Absent,
        other => LightcrafterError::Usb(other.to_string()),
    }
}

impl UsbTransport {
    /// Opens the first LightCrafter 4500 on the bus.
    pub fn open() -> Result<Self, LightcrafterError> {
        let context = Context::new().map_err(usb_error)?;
        let device = context
            .devices()
            .map_err(usb_error)?
            .iter()
            .find(|d| {
                d.device_descriptor().is_ok_and(|desc| {
                    desc.vendor_id() == VENDOR_ID && desc.product_id() == PRODUCT_ID
                })
            })
            .ok_or(LightcrafterError::Absent)?;
        let config = device.active_config_descriptor().map_err(usb_error)?;
        // The first interface with an interrupt endpoint each way.
        let mut found = None;
        for interface in config.interfaces() {
            for alt in interface.descriptors() {
                let find = |dir| {
                    alt.endpoint_descriptors()
                        .find(|e| {
                            e.transfer_type() == TransferType::Interrupt && e.direction() == dir
                        })
                        .map(|e| e.address())
                };
                if let (Some(i), Some(o)) = (find(Direction::In), find(Direction::Out)) {
                    found = Some((alt.interface_number(), i, o));
                    break;
                }
            }
        }
        let (interface, endpoint_in, endpoint_out) = found.ok_or_else(|| {
            LightcrafterError::Usb("the device has no interrupt endpoints".to_string())
        })?;
        let handle = device.open().map_err(usb_error)?;
        if handle.kernel_driver_active(interface).unwrap_or(false) {
            handle.detach_kernel_driver(interface).map_err(usb_error)?;
        }
        handle.claim_interface(interface).map_err(usb_error)?;
        Ok(Self {
            handle,
            interface,
            endpoint_in,
            endpoint_out,
        })
    }
}

impl HidTransport for UsbTransport {
    fn write_report(&mut self, report: &[u8; REPORT_LEN]) -> Result<(), LightcrafterError> {
        let written = self
            .handle
            .write_interrupt(self.endpoint_out, report, TIMEOUT)
            .map_err(|e| match e {
                rusb::Error::Timeout => LightcrafterError::Timeout("a report write"),
                other => usb_error(other),
            })?;
        if written != REPORT_LEN {
            return Err(LightcrafterError::Usb(format!(
                "wrote {written} of {REPORT_LEN} bytes"
            )));
        }
        Ok(())
    }

    fn read_report(&mut self) -> Result<[u8; REPORT_LEN], LightcrafterError> {
        let mut report = [0u8; REPORT_LEN];
        self.handle
            .read_interrupt(self.endpoint_in, &mut report, TIMEOUT)
            .map_err(|e| match e {
                rusb::Error::Timeout => LightcrafterError::Timeout("a reply"),
                other => usb_error(other),
            })?;
        Ok(report)
    }
}

impl Drop for UsbTransport {
    fn drop(&mut self) {
        // Best effort: give the interface back (and the kernel driver with it).
        let _ = self.handle.release_interface(self.interface);
        let _ = self.handle.attach_kernel_driver(self.interface);
    }
}

/// Opens the LightCrafter on USB, ready for [`LightCrafter::program_cps`](super::LightCrafter).
pub fn open() -> Result<super::LightCrafter<UsbTransport>, LightcrafterError> {
    Ok(super::LightCrafter::new(UsbTransport::open()?))
}
