//! The tokio links: Modbus TCP conversion, late replies dropped by
//! transaction id, progress kept across dropped futures.

use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use yosemitech_rtu::crc_ok;
use yosemitech_rtu::mbap::{MAX_MBAP_ADU, adu_to_rtu, rtu_to_adu};
use yosemitech_rtu::transport::{AsyncLink, MbapLink};

const READ_FLOAT_REQUEST: [u8; 8] = [0x01, 0x03, 0x28, 0x00, 0x00, 0x02, 0xCD, 0xAB];
const READ_FLOAT_REPLY: [u8; 9] = [0x01, 0x03, 0x04, 0x33, 0x33, 0xF3, 0x40, 0x40, 0x78];

fn adu(rtu: &[u8], transaction: u16) -> Vec<u8> {
    let mut out = [0u8; MAX_MBAP_ADU];
    let n = rtu_to_adu(rtu, transaction, &mut out).unwrap();
    out[..n].to_vec()
}

async fn read_frame<L: AsyncLink>(link: &mut L, len: usize) -> Vec<u8> {
    let mut frame = vec![0u8; len];
    let mut got = 0;
    while got < len {
        got += link.read(&mut frame[got..]).await.unwrap();
    }
    frame
}

#[tokio::test(flavor = "current_thread")]
async fn mbap_link_converts_and_drops_late_replies() {
    let (near, mut gateway) = tokio::io::duplex(1024);
    let mut link = MbapLink::new(near);
    link.write_frame(&READ_FLOAT_REQUEST).await.unwrap();
    let mut request = [0u8; 12];
    gateway.read_exact(&mut request).await.unwrap();
    let mut rtu = [0u8; 256];
    let (header, n) = adu_to_rtu(&request, &mut rtu).unwrap();
    assert_eq!((header.transaction, &rtu[..n]), (1, &READ_FLOAT_REQUEST[..]));
    // A late reply to an earlier request, then the reply, one byte at a time.
    let mut replies = adu(&READ_FLOAT_REPLY, 0);
    replies.extend(adu(&READ_FLOAT_REPLY, 1));
    for byte in replies {
        gateway.write_all(&[byte]).await.unwrap();
    }
    let frame = read_frame(&mut link, READ_FLOAT_REPLY.len()).await;
    assert_eq!(frame, READ_FLOAT_REPLY);
    assert!(crc_ok(&frame));
    // Nothing else is pending: the late reply was dropped.
    let mut more = [0u8; 4];
    assert!(tokio::time::timeout(Duration::from_millis(50), link.read(&mut more)).await.is_err());
}

#[tokio::test(flavor = "current_thread")]
async fn mbap_link_resumes_a_read_whose_future_was_dropped() {
    let (near, mut gateway) = tokio::io::duplex(1024);
    let mut link = MbapLink::new(near);
    link.write_frame(&READ_FLOAT_REQUEST).await.unwrap();
    let reply = adu(&READ_FLOAT_REPLY, 1);
    gateway.write_all(&reply[..5]).await.unwrap();
    let mut buf = [0u8; 16];
    // Half an ADU, then the read is dropped; the half stays in the link.
    assert!(tokio::time::timeout(Duration::from_millis(20), link.read(&mut buf)).await.is_err());
    gateway.write_all(&reply[5..]).await.unwrap();
    assert_eq!(read_frame(&mut link, READ_FLOAT_REPLY.len()).await, READ_FLOAT_REPLY);
    // A malformed header is an error, not a frame.
    link.write_frame(&READ_FLOAT_REQUEST).await.unwrap();
    gateway.write_all(&[0, 2, 0, 1, 0, 3, 1, 3, 0]).await.unwrap();
    let error = link.read(&mut buf).await.unwrap_err();
    assert_eq!(error.kind(), std::io::ErrorKind::InvalidData);
}
