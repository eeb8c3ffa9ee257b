//! What every route's wire types share: the deserialization rules and the macros that declare
//! request types with the common members ([`de`]), the members as stated before validation
//! ([`params`]), the measured values every distance answer carries ([`measured`]), the rig's
//! wire shapes ([`rig`]), the calibration options ([`calibration`]), what the image routes
//! share on the wire ([`images`]), and the OpenAPI glue ([`openapi`]). Each endpoint's own request and response types live beside its
//! route, in [`super::routes`].

pub mod calibration;
pub mod de;
pub mod images;
pub mod measured;
pub mod openapi;
pub mod params;
pub mod rig;
