/// @brief The wire acks of the scene's edit outcomes (scene/outcomes.h): the session's one place
/// that turns them into sculpt.v1 messages, refusals through ToWireError.
#ifndef SCULPT_SERVER_NET_WIRE_ACKS_H_
#define SCULPT_SERVER_NET_WIRE_ACKS_H_

#include "scene/outcomes.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::server {

/// A SkinAck: accepted with the outcome's details, or refused with the Error of its status (the
/// outcome's client_seq in both). Fields left at zero are not sent (proto3).
v1::SkinAck ToWireAck(const SkinOutcome& outcome);
/// A PaintAck, likewise.
v1::PaintAck ToWireAck(const PaintOutcome& outcome);
/// A ModelAck: a validity refusal carries its reason, cell, direction, span and detail (no
/// Error); any other refusal the Error.
v1::ModelAck ToWireAck(const ModelOutcome& outcome);
/// An UndoAck: accepted with the target, the replays and the depths left (a duplicate with
/// neither), or refused with the Error of its status (and the undo's sequence when it was logged).
v1::UndoAck ToWireAck(const UndoCommandOutcome& outcome);
/// A HistoryAnswer: the entries, counts and cleared reason, or the Error of a refusal (no entries).
v1::HistoryAnswer ToWireAnswer(const HistoryOutcome& outcome);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_WIRE_ACKS_H_
