/// @brief SculptureFeed: sharing publication and the state-hash seals.
#include "sculpt/haptics/sculpture_feed.h"

#include <chrono>

#include "sculpt/haptics/sculpture_snapshot.h"

namespace sculpt::haptics {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

SculptureFeed::SculptureFeed(SnapshotPublisher* publisher, bool seal)
    : publisher_(publisher), seal_(seal) {}

SculptureFeed::~SculptureFeed() = default;

void SculptureFeed::Publish(std::shared_ptr<const levelset::Sculpture> sculpture, uint64_t seq) {
  if (!sculpture) return;
  std::lock_guard<std::mutex> lock(mu_);
  Held h;
  h.sculpture = sculpture;
  if (seal_) {
    const auto t0 = Clock::now();
    h.hash = sculpture->StateHash();
    stats_.seal_ms += MsSince(t0);
  }
  PublishLocked(std::move(sculpture));
  h.version = publisher_->Current()->version;
  ++stats_.published;
  stats_.last_seq = seq;
  stats_.last_version = h.version;
  held_.push_back(std::move(h));
  // The publisher still retains the newest kRetained; the one let go here is past the loop.
  while (held_.size() > kHeld) {
    CheckLocked(held_.front());
    held_.pop_front();
  }
}

void SculptureFeed::PublishLocked(std::shared_ptr<const levelset::Sculpture> sculpture) {
  if (!window_centre_) {
    last_windowed_.reset();
    publisher_->Publish(std::make_shared<const SculptureSnapshot>(std::move(sculpture)));
    return;
  }
  const auto t0 = Clock::now();
  last_centre_ = window_centre_();
  auto snapshot = std::make_shared<const SculptureSnapshot>(
      std::move(sculpture), last_centre_, window_radius_, last_windowed_.get());
  stats_.window_ms += MsSince(t0);
  if (snapshot->window_values() > 0) ++stats_.windows;
  last_windowed_ = snapshot;
  publisher_->Publish(std::move(snapshot));
}

void SculptureFeed::SetWindow(std::function<Vec3()> centre, double radius) {
  std::lock_guard<std::mutex> lock(mu_);
  window_centre_ = std::move(centre);
  window_radius_ = radius;
}

bool SculptureFeed::RecentreWindow() {
  std::lock_guard<std::mutex> lock(mu_);
  if (!window_centre_ || held_.empty()) return false;
  const Vec3 now = window_centre_();
  if (!now.IsFinite() || (now - last_centre_).Length() <= 0.25 * window_radius_) return false;
  // The same copy again: its seal is the one taken when it was first published.
  Held h = held_.back();
  PublishLocked(h.sculpture);
  h.version = publisher_->Current()->version;
  stats_.last_version = h.version;
  ++stats_.recentred;
  held_.push_back(std::move(h));
  while (held_.size() > kHeld) {
    CheckLocked(held_.front());
    held_.pop_front();
  }
  return true;
}

void SculptureFeed::CheckLocked(const Held& h) {
  if (!seal_) return;
  const auto t0 = Clock::now();
  const uint64_t now = h.sculpture->StateHash();
  stats_.seal_ms += MsSince(t0);
  ++stats_.checked;
  if (now != h.hash) {
    ++stats_.changed;
    changed_.push_back(h.version);
  }
}

void SculptureFeed::CheckHeld() {
  std::lock_guard<std::mutex> lock(mu_);
  for (const Held& h : held_) CheckLocked(h);
  // Each seal is checked once; the publisher keeps its own references for the loop.
  held_.clear();
}

SculptureFeed::Stats SculptureFeed::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

std::vector<uint64_t> SculptureFeed::changed_versions() const {
  std::lock_guard<std::mutex> lock(mu_);
  return changed_;
}

}  // namespace sculpt::haptics
