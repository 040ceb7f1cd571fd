// AsyncEnvironmentEstimator: environment lights and map on a worker thread, newest image wins.
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "lights_internal.h"

namespace mixray::tracking {

struct AsyncEnvironmentEstimator::Impl {
    EnvironmentCamera camera;
    EnvironmentLightOptions options;
    int map_width = 512;

    struct Job {
        Image image;
        std::string refused;  // why the submitted view could not be taken
        int64_t stamp_ns = 0;
    };

    mutable std::mutex mutex;
    std::condition_variable wake;  // a job arrived or the estimator is closing
    std::condition_variable idle;  // a job finished
    std::optional<Job> pending;
    bool busy = false;
    bool stop = false;
    // Swapped whole, so latest() copies outside the lock and never waits on a running job.
    std::shared_ptr<const Estimate<EnvironmentEstimate>> latest =
        std::make_shared<Estimate<EnvironmentEstimate>>();
    std::thread worker;

    // Built on the worker's first job: the lens unprojection of every pixel is the costly part.
    std::optional<Result<detail::FisheyeGeometry>> geometry;

    void run() {
        std::unique_lock lock(mutex);
        while (true) {
            wake.wait(lock, [&] { return stop || pending.has_value(); });
            if (stop)
                return;
            Job job = std::move(*pending);
            pending.reset();
            busy = true;
            // Only this thread replaces `latest`, so it can be copied unlocked.
            const auto previous = latest;
            lock.unlock();
            auto next = std::make_shared<Estimate<EnvironmentEstimate>>(*previous);
            process(job, *next);
            lock.lock();
            latest = std::move(next);
            busy = false;
            idle.notify_all();
        }
    }

    void process(const Job& job, Estimate<EnvironmentEstimate>& estimate) {
        if (!job.refused.empty()) {
            estimate.keep(job.refused, job.stamp_ns);
            return;
        }
        if (!geometry)
            geometry = detail::FisheyeGeometry::build(camera);
        if (!*geometry) {
            estimate.keep(geometry->status().message(), job.stamp_ns);
            return;
        }
        auto lights = detail::environmentLights(job.image.view(), camera, **geometry, options);
        if (!lights) {
            estimate.keep(lights.status().message(), job.stamp_ns);
            return;
        }
        auto map = environmentMapFromFisheye(job.image.view(), camera, map_width);
        if (!map) {
            estimate.keep(map.status().message(), job.stamp_ns);
            return;
        }
        estimate.update(
            {std::move(lights).value(), std::make_shared<const FloatImage>(std::move(map).value())},
            job.stamp_ns);
    }
};

AsyncEnvironmentEstimator::AsyncEnvironmentEstimator(EnvironmentCamera camera,
                                                     EnvironmentLightOptions options, int map_width)
    : impl_(std::make_unique<Impl>()) {
    impl_->camera = std::move(camera);
    impl_->options = options;
    impl_->map_width = map_width;
    impl_->worker = std::thread([impl = impl_.get()] { impl->run(); });
}

AsyncEnvironmentEstimator::~AsyncEnvironmentEstimator() {
    {
        std::lock_guard lock(impl_->mutex);
        impl_->stop = true;
    }
    impl_->wake.notify_all();
    // A job already running finishes; one still waiting is dropped.
    impl_->worker.join();
}

void AsyncEnvironmentEstimator::submit(const ImageView& env, int64_t stamp_ns) {
    Impl::Job job;
    job.stamp_ns = stamp_ns;
    const Status ok = detail::checkColorImage(env, "environment image");
    if (ok)
        job.image = Image::copyOf(env);
    else
        job.refused = ok.message();
    {
        std::lock_guard lock(impl_->mutex);
        impl_->pending = std::move(job);
    }
    impl_->wake.notify_one();
}

Estimate<EnvironmentEstimate> AsyncEnvironmentEstimator::latest() const {
    std::shared_ptr<const Estimate<EnvironmentEstimate>> snapshot;
    {
        std::lock_guard lock(impl_->mutex);
        snapshot = impl_->latest;
    }
    return *snapshot;
}

void AsyncEnvironmentEstimator::drain() {
    std::unique_lock lock(impl_->mutex);
    impl_->idle.wait(lock, [&] { return !impl_->pending && !impl_->busy; });
}

}  // namespace mixray::tracking
