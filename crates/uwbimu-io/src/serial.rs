//! The UWB modules' serial protocols: the Nooploop LinkTrack frames ([`linktrack`]), the DWM1001
//! UART TLV `dwm_loc_get` response ([`dwm1001`]) and the resynchronising scan they share
//! (`resync`).

pub mod dwm1001;
pub mod linktrack;
mod resync;
