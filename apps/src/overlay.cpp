// Tracking overlays (overlay.h), drawn with OpenCV.
#include "overlay.h"

#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "mixray/tracking/overlay.h"

namespace mixray::cli {
namespace {

cv::Scalar colourOf(const tracking::OverlayColour& c) {
    return cv::Scalar(c[0], c[1], c[2]);
}

cv::Point2d at(const Eigen::Vector2d& p) {
    return {p.x(), p.y()};
}

void text(cv::Mat& m, const std::string& s, cv::Point where, const cv::Scalar& colour) {
    cv::putText(m, s, where, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(m, s, where, cv::FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv::LINE_AA);
}

}  // namespace

Image drawTrackingOverlay(const tracking::TrackedFrame& frame,
                          const tracking::TrackingSetup& setup) {
    const ImageView in = frame.color.image();
    Image out(ImageDesc::packed(PixelFormat::kRGB8, in.desc.width, in.desc.height));
    cv::Mat m(in.desc.height, in.desc.width, CV_8UC3, out.mutableView().data,
              static_cast<size_t>(out.view().desc.stride_bytes));
    const cv::Mat src(in.desc.height, in.desc.width, CV_8UC3, const_cast<uint8_t*>(in.data),
                      static_cast<size_t>(in.desc.stride_bytes));
    if (in.desc.format == PixelFormat::kBGR8)
        cv::cvtColor(src, m, cv::COLOR_BGR2RGB);
    else
        src.copyTo(m);

    const tracking::TrackingOverlay overlay = tracking::trackingOverlay(frame, setup);
    for (const auto& p : overlay.polygons) {
        std::vector<cv::Point> poly;
        for (const Eigen::Vector2d& c : p.points)
            poly.emplace_back(static_cast<int>(std::lround(c.x())),
                              static_cast<int>(std::lround(c.y())));
        cv::polylines(m, poly, true, colourOf(p.colour), 1, cv::LINE_AA);
        if (!poly.empty())
            text(m, p.label, poly[0] + cv::Point(2, -4), colourOf(p.colour));
    }
    for (const auto& l : overlay.lines) {
        if (l.arrow)
            cv::arrowedLine(m, at(l.from), at(l.to), colourOf(l.colour), l.width, cv::LINE_AA, 0,
                            0.2);
        else
            cv::line(m, at(l.from), at(l.to), colourOf(l.colour), l.width, cv::LINE_AA);
    }
    for (const auto& c : overlay.circles)
        cv::circle(m, at(c.centre), static_cast<int>(std::lround(c.radius)), colourOf(c.colour), 1,
                   cv::LINE_AA);
    for (const auto& t : overlay.texts)
        text(m, t.text,
             cv::Point(static_cast<int>(std::lround(t.at.x())), static_cast<int>(t.at.y())),
             colourOf(t.colour));
    return out;
}

}  // namespace mixray::cli
