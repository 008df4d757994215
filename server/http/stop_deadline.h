// The daemon's stop, bounded: what a stop waits for (the frame in progress, sessions closing, HTTP
// workers, the device) is never an edit, as the store commits each edit before it is acknowledged; a stop
// still waiting when its deadline passes is ended where it stands, saying what it waited for.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace refract::http {

class StopDeadline {
public:
    // `overdue` is called once, on a thread of its own, with the step the stop is in when `deadline`
    // has passed (refractd exits there); never once this is destroyed.
    StopDeadline(std::chrono::milliseconds deadline, std::function<void(const std::string& step)> overdue);
    ~StopDeadline();
    StopDeadline(const StopDeadline&) = delete;
    StopDeadline& operator=(const StopDeadline&) = delete;

    // The step the stop waits for from now on.
    void step(std::string name);

private:
    void watch(std::chrono::milliseconds deadline);

    std::function<void(const std::string&)> overdue_;
    std::mutex mutex_;
    std::condition_variable finished_;
    std::string step_ = "the start of the stop";
    bool done_ = false;
    std::thread thread_;
};

}  // namespace refract::http
