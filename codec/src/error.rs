//! The codec's typed error.

use thiserror::Error;

/// Everything that can go wrong while encoding or decoding, split by cause.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum CodecError {
    /// The data does not start with the `.ezw` magic bytes.
    #[error("not an .ezw file (wrong magic bytes)")]
    BadMagic,
    /// The container version is newer than this decoder understands.
    #[error("unsupported .ezw version {0} (this build reads version {1})")]
    UnsupportedVersion(u16, u16),
    /// The file ends before the header (or the nodata mask) is complete.
    #[error("truncated .ezw header: {0}")]
    TruncatedHeader(&'static str),
    /// The header checksum does not match its contents.
    #[error(
        "corrupt .ezw header: checksum mismatch (stored {stored:08x}, computed {computed:08x})"
    )]
    HeaderChecksum {
        /// Checksum stored in the file.
        stored: u32,
        /// Checksum computed over the header bytes.
        computed: u32,
    },
    /// A header field holds a value no encoder writes.
    #[error("corrupt .ezw header: {0}")]
    InvalidHeader(String),
    /// Width or height is zero, or their product overflows.
    #[error("invalid raster dimensions {width}x{height}")]
    Dimensions {
        /// Claimed width.
        width: u64,
        /// Claimed height.
        height: u64,
    },
    /// Decoding would exceed a configured resource limit.
    #[error("{what} ({needed}) exceeds the limit ({limit})")]
    LimitExceeded {
        /// What was being limited.
        what: &'static str,
        /// Amount the file asks for.
        needed: u64,
        /// The configured limit.
        limit: u64,
    },
    /// A chunk checksum failed or the file has trailing garbage (strict decoding, or
    /// damage in a section nothing can be decoded without).
    #[error("damaged .ezw file: {section} fails its checksum at byte {offset}")]
    Damaged {
        /// The damaged section.
        section: &'static str,
        /// File offset where the damage starts.
        offset: u64,
    },
    /// The encoder or decoder was given parameters it cannot honour.
    #[error("invalid parameters: {0}")]
    InvalidParameters(String),
    /// Reading the bytes of a stream failed (a file or a remote source behind
    /// [`crate::tiles::ByteSource`]).
    #[error("reading failed: {0}")]
    Read(String),
    /// The raster holds values the coder cannot represent (an infinite sample, a range
    /// too wide for exact integer coding); the message says what would code it.
    #[error("cannot code these samples: {0}")]
    UnsupportedValues(String),
}
