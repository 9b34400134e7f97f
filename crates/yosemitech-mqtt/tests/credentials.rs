//! Credentials: where they come from, which files are refused, and that the
//! password shows in no `Debug`, `Display` or error text.

use std::os::unix::fs::PermissionsExt;
use std::path::PathBuf;

use yosemitech_mqtt::{
    ConfigError, CredentialsError, CredentialsSource, MemoryOutbox, MqttConfig, PASSWORD_VAR, Publisher, StartError,
    USERNAME_VAR,
};

const PASSWORD: &str = "Very-s3cret-passw0rd";

fn file_with_mode(name: &str, content: &str, mode: u32) -> PathBuf {
    let path = yosemitech_tests::scratch_dir("mqtt-credentials").join(name);
    std::fs::write(&path, content).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
    path
}

#[test]
fn a_file_readable_by_group_or_others_is_refused_naming_the_file_and_the_fix() {
    for mode in [0o644, 0o640, 0o604, 0o660, 0o606, 0o602, 0o620] {
        let path = file_with_mode("open.credentials", &format!("station:{PASSWORD}\n"), mode);
        let error = CredentialsSource::File(path.clone()).load().unwrap_err();
        assert!(
            matches!(error, CredentialsError::FileNotOwnerOnly { mode: found, .. } if found == mode),
            "{mode:o}: {error:?}"
        );
        let message = error.to_string();
        assert!(message.contains(&path.display().to_string()), "{message}");
        assert!(message.contains("chmod 600"), "{message}");
        assert!(!message.contains(PASSWORD) && !format!("{error:?}").contains(PASSWORD));
    }
}

#[test]
fn an_owner_only_file_is_read() {
    for mode in [0o600, 0o400] {
        let path = file_with_mode("ok.credentials", &format!("station:{PASSWORD}:with-colon\r\n"), mode);
        let credentials = CredentialsSource::File(path).load().unwrap().unwrap();
        assert_eq!(credentials.username, "station");
        assert_eq!(credentials.password.expose(), format!("{PASSWORD}:with-colon"));
        let shown = format!("{credentials:?}");
        assert!(shown.contains("station") && !shown.contains(PASSWORD), "{shown}");
    }
}

#[test]
fn a_malformed_file_is_refused_without_showing_its_content() {
    for content in [PASSWORD.to_owned(), format!(":{PASSWORD}"), format!("a:{PASSWORD}\nb:c\n")] {
        let path = file_with_mode("bad.credentials", &content, 0o600);
        let error = CredentialsSource::File(path.clone()).load().unwrap_err();
        assert!(matches!(error, CredentialsError::Malformed { .. }), "{error:?}");
        assert!(error.to_string().contains(&path.display().to_string()));
        assert!(!error.to_string().contains(PASSWORD) && !format!("{error:?}").contains(PASSWORD));
    }
    let missing = CredentialsSource::File("/nonexistent/mqtt.credentials".into()).load().unwrap_err();
    assert!(missing.to_string().contains("/nonexistent/mqtt.credentials"), "{missing}");
}

#[test]
fn environment_credentials_name_the_missing_variable() {
    let source = CredentialsSource::Environment;
    let both = |name: &str| match name {
        USERNAME_VAR => Some("station".to_owned()),
        PASSWORD_VAR => Some(PASSWORD.to_owned()),
        _ => None,
    };
    let credentials = source.load_with(both).unwrap().unwrap();
    assert_eq!(credentials.password.expose(), PASSWORD);
    assert!(!format!("{credentials:?}").contains(PASSWORD));

    let no_password = source.load_with(|name| (name == USERNAME_VAR).then(|| "station".to_owned())).unwrap_err();
    assert!(no_password.to_string().contains(PASSWORD_VAR), "{no_password}");
    let no_user = source.load_with(|name| (name == PASSWORD_VAR).then(|| PASSWORD.to_owned())).unwrap_err();
    assert!(no_user.to_string().contains(USERNAME_VAR), "{no_user}");
    assert_eq!(CredentialsSource::None.load().unwrap(), None);
}

#[test]
fn the_publisher_refuses_to_start_with_a_world_readable_file() {
    let path = file_with_mode("world.credentials", &format!("station:{PASSWORD}\n"), 0o644);
    let config: MqttConfig = toml::from_str(&format!(
        "host = \"127.0.0.1\"\nport = 1\nclient_id = \"station\"\ncredentials = {{ file = {:?} }}\n",
        path.display().to_string()
    ))
    .unwrap();
    assert!(matches!(config.check(), Err(ConfigError::Credentials(CredentialsError::FileNotOwnerOnly { .. }))));
    let Err(error) = Publisher::start(&config, MemoryOutbox::new()) else {
        panic!("the publisher started with a world-readable credentials file");
    };
    assert!(matches!(error, StartError::Config(_)), "{error:?}");
    assert!(error.to_string().contains("chmod 600"), "{error}");
    assert!(!error.to_string().contains(PASSWORD));
}

#[test]
fn the_mqtt_section_parses_with_defaults_and_refuses_unknown_keys() {
    #[derive(serde::Deserialize)]
    struct Station {
        mqtt: MqttConfig,
    }
    let station: Station = toml::from_str(
        "[mqtt]\nhost = \"broker.example.org\"\nclient_id = \"river-01\"\ncredentials = \"environment\"\n\
         [mqtt.publisher]\nmax_in_flight = 32\n",
    )
    .unwrap();
    let mqtt = station.mqtt;
    assert_eq!(mqtt.port(), 1883);
    assert_eq!(mqtt.keep_alive_secs, 30);
    assert_eq!(mqtt.topic_prefix, "yosemitech/v1");
    assert_eq!(mqtt.credentials, CredentialsSource::Environment);
    assert_eq!(mqtt.publisher.max_in_flight, 32);
    assert_eq!(mqtt.publisher.poll_interval_ms, 1000);
    assert!(!mqtt.require_subscriber, "a reading nobody subscribed to counts as published unless asked");
    let required: MqttConfig = toml::from_str("host = \"h\"\nclient_id = \"c\"\nrequire_subscriber = true\n").unwrap();
    assert!(required.require_subscriber);

    let misspelt = toml::from_str::<MqttConfig>("host = \"h\"\nclient_id = \"c\"\nkeep_alive_sec = 5\n").unwrap_err();
    assert!(misspelt.to_string().contains("keep_alive_sec"), "{misspelt}");
    let bad_source = toml::from_str::<MqttConfig>("host = \"h\"\nclient_id = \"c\"\ncredentials = \"vault\"\n");
    assert!(bad_source.is_err());
}

#[test]
fn check_refuses_what_cannot_work_before_any_connection() {
    let base: MqttConfig = toml::from_str("host = \"h\"\nclient_id = \"c\"\n").unwrap();
    assert!(base.check().is_ok());
    type Breakage = fn(&mut MqttConfig);
    let cases: [(&str, Breakage); 5] = [
        ("host", |c| c.host.clear()),
        ("client_id", |c| c.client_id = " ".into()),
        ("topic_prefix", |c| c.topic_prefix = "a/#".into()),
        ("max_in_flight", |c| c.publisher.max_in_flight = 0),
        ("reconnect_min_ms", |c| c.publisher.reconnect_max_ms = 0),
    ];
    for (key, break_it) in cases {
        let mut config = base.clone();
        break_it(&mut config);
        let error = config.check().unwrap_err();
        assert!(error.to_string().contains(key), "{key}: {error}");
    }
    let not_pem = file_with_mode("ca.pem", "not a certificate\n", 0o644);
    let mut tls: MqttConfig = toml::from_str(&format!(
        "host = \"h\"\nclient_id = \"c\"\n[tls]\nca_file = {:?}\n",
        not_pem.display().to_string()
    ))
    .unwrap();
    assert_eq!(tls.port(), 8883);
    let error = tls.check().unwrap_err();
    assert!(matches!(error, ConfigError::CaFile { .. }), "{error:?}");
    assert!(error.to_string().contains(&not_pem.display().to_string()), "{error}");
    tls.tls = None;
    assert!(tls.check().is_ok());
}
