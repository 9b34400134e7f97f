//! The rustls client configuration for a TLS broker connection.

use std::sync::Arc;

use rustls::pki_types::CertificateDer;
use rustls::pki_types::pem::PemObject;

use crate::config::{ConfigError, TlsConfig};

/// A rustls client config (ring provider, TLS 1.2 and 1.3) trusting the CA
/// file, or the operating system's roots when there is none.
pub fn client_config(tls: &TlsConfig) -> Result<Arc<rustls::ClientConfig>, ConfigError> {
    let mut roots = rustls::RootCertStore::empty();
    match &tls.ca_file {
        Some(path) => {
            let ca_error = |reason: String| ConfigError::CaFile { path: path.clone(), reason };
            let certificates = CertificateDer::pem_file_iter(path)
                .map_err(|error| ca_error(error.to_string()))?
                .collect::<Result<Vec<_>, _>>()
                .map_err(|error| ca_error(error.to_string()))?;
            if certificates.is_empty() {
                return Err(ca_error("holds no PEM certificate".into()));
            }
            for certificate in certificates {
                roots.add(certificate).map_err(|error| ca_error(error.to_string()))?;
            }
        }
        None => {
            let native = rustls_native_certs::load_native_certs();
            for error in &native.errors {
                tracing::warn!(%error, "skipping an operating-system root certificate");
            }
            let (added, _ignored) = roots.add_parsable_certificates(native.certs);
            if added == 0 {
                return Err(ConfigError::CaFile {
                    path: "(operating-system roots)".into(),
                    reason: "no usable root certificate; set mqtt.tls.ca_file".into(),
                });
            }
        }
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|error| ConfigError::CaFile {
            path: tls.ca_file.clone().unwrap_or_default(),
            reason: error.to_string(),
        })?
        .with_root_certificates(roots)
        .with_no_client_auth();
    Ok(Arc::new(config))
}
