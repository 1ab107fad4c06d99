// Test mode only (?test=iwer): Meta's WebXR emulation runtime stands in for a headset, so the
// browser tests can enter `immersive-vr` in headless chromium and move an emulated headset and
// controllers (window.hrcXrDevice: position/quaternion, controllers.left/right,
// controllers.right.updateButtonValue('squeeze', 1)).
import { XRDevice, metaQuest3 } from 'iwer';

const device = new XRDevice(metaQuest3);
device.installRuntime({ forceInstall: true });
device.stereoEnabled = false; // one view fills the canvas: the screenshots show what an eye sees
window.hrcXrDevice = device;
