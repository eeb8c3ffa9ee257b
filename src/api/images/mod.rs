//! What the image routes (`/depth-map`, `/match`, and the calibration and rectification routes
//! after them) share, one concern a file:
//! - [`form`]: the multipart form read after the request's admission, and
//!   [`form::ImagePair`], the extractor that opens every image route (parts, sizes, the pair's
//!   check, the rig);
//! - [`parts`]: the form's parts by name;
//! - [`rig`]: the rig from a `rig` part or a `calibration` file, through the one constructor
//!   every rig goes through;
//! - [`maps`]: the rectification maps of the raw rigs seen lately, cached within the budget;
//! - [`raw`]: whether a request rectifies its pair, the memory that takes, the frames read
//!   through the maps, and the row check of a pair sent as rectified;
//! - [`output`]: a file answer with its media type and name, and `Server-Timing`;
//! - [`limits`]: what the server accepts: image sizes, the matcher's settings mapped onto the
//!   query's names, and what to shrink when a request cannot fit;
//! - [`work`]: a compute slot taken and the memory reserved when the work starts (not while
//!   the body arrives), the work run on a blocking thread that stops when its request is
//!   abandoned, the pair decoded, the matcher's stages for `Server-Timing`.
//!
//! It sits between [`super::validate`] and [`super::routes`]: the routes use it, it uses
//! none of them.

pub mod form;
pub mod limits;
pub mod maps;
pub mod output;
pub mod parts;
pub mod raw;
pub mod rig;
pub mod work;

pub use form::{ImageForm, ImagePair, Job};
pub use parts::Parts;
