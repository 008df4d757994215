#include "http/stop_deadline.h"

namespace refract::http {

StopDeadline::StopDeadline(std::chrono::milliseconds deadline,
                           std::function<void(const std::string&)> overdue)
    : overdue_(std::move(overdue)), thread_([this, deadline] { watch(deadline); }) {}

StopDeadline::~StopDeadline() {
    {
        std::lock_guard lock(mutex_);
        done_ = true;
    }
    finished_.notify_all();
    thread_.join();
}

void StopDeadline::step(std::string name) {
    std::lock_guard lock(mutex_);
    step_ = std::move(name);
}

void StopDeadline::watch(std::chrono::milliseconds deadline) {
    std::unique_lock lock(mutex_);
    if (finished_.wait_for(lock, deadline, [this] { return done_; })) return;
    const std::string step = step_;
    lock.unlock();
    overdue_(step);
}

}  // namespace refract::http
