//! ROS 2 messages: the ros2msg schema parser ([`msg_schema`]), the generic CDR decoder driven by
//! it ([`cdr`]), the message type definitions ([`types`]), the payload encoders of the messages
//! we write ([`payloads`]) and the ROS 2 outputs of the live node ([`out`]).

pub mod cdr;
pub mod msg_schema;
pub mod out;
pub mod payloads;
pub mod types;
