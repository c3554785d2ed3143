//! Rust errors as Python exceptions, with the command line's one-line messages:
//! `ValueError` for bad arguments, `OSError` (or `FileNotFoundError`) for files that
//! cannot be opened or written, `CodecError` for everything the data itself causes.

use std::io;

use pyo3::exceptions::{PyException, PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::PyErr;
use wavemesh::dem::DemError;
use wavemesh_codec::CodecError as RustCodecError;

pyo3::create_exception!(
    _wavemesh,
    CodecError,
    PyException,
    "A .ezw stream could not be decoded (damaged, truncated, not a .ezw stream, over a \
     limit) or a raster could not be encoded (samples the coder cannot hold)."
);

/// A codec error: bad encoder parameters are a `ValueError`, the rest a `CodecError`
/// (a limit's message names the keywords that raise it).
pub fn codec_error(error: RustCodecError) -> PyErr {
    match error {
        RustCodecError::InvalidParameters(_) => PyValueError::new_err(error.to_string()),
        RustCodecError::LimitExceeded { .. } => CodecError::new_err(format!(
            "{error}; raise max_samples= or max_memory= if the data is trusted"
        )),
        other => CodecError::new_err(other.to_string()),
    }
}

/// An I/O error on a file, its message naming the file.
pub fn io_error(path: &std::path::Path, error: &io::Error) -> PyErr {
    let message = format!("{}: {error}", path.display());
    match error.kind() {
        io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}

/// A DEM reader's error: files that cannot be opened are an `OSError`, files over a
/// limit name the keyword that lifts it, anything else about the file is a `CodecError`.
pub fn dem_error(error: DemError) -> PyErr {
    let hint = match &error {
        DemError::Io { path, source } => return io_error(path, source),
        DemError::TooLarge { .. } => "; raise max_samples= if the file is trusted",
        DemError::OverMemory { .. } => "; raise max_memory= if the machine has it",
        DemError::LossyInput(_) => "; accept_lossy_input=True reads them anyway",
        _ => "",
    };
    CodecError::new_err(format!("{error}{hint}"))
}
