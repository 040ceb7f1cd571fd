// Texture and EnvironmentMap (assets.h): loading, bilinear sampling, the lat-long direction
// convention.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "image_file.h"
#include "mixray/render/assets.h"

namespace mixray::render {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Wraps an integer index into [0, n).
int wrapIndex(int i, int n) {
    const int r = i % n;
    return r < 0 ? r + n : r;
}

}  // namespace

Texture::Texture(int width, int height, std::vector<Rgb> texels)
    : width_(width), height_(height), texels_(std::move(texels)) {
    // A size that disagrees with the texel count would make texel() read out of bounds.
    if (width_ <= 0 || height_ <= 0 ||
        texels_.size() != static_cast<size_t>(width_) * static_cast<size_t>(height_)) {
        width_ = 0;
        height_ = 0;
        texels_.clear();
    }
}

Result<Texture> Texture::load(const std::filesystem::path& path) {
    Result<detail::LinearImage> image = detail::readLinearImage(path);
    if (!image)
        return image.status().withContext("loading texture");
    return Texture(image->width, image->height, std::move(image->texels));
}

Rgb Texture::sample(const Eigen::Vector2f& uv) const {
    if (texels_.empty() || !uv.allFinite())
        return Rgb::Zero();
    // Wrap u into [0,1) before scaling so huge values cannot overflow the integer conversion.
    const float u = uv.x() - std::floor(uv.x());
    const float v = std::clamp(uv.y(), 0.0f, 1.0f);
    // Texel centres sit at (i + 0.5) / size.
    const float x = u * static_cast<float>(width_) - 0.5f;
    const float y = v * static_cast<float>(height_) - 0.5f;
    const float fx = std::floor(x);
    const float fy = std::floor(y);
    const float ax = x - fx;
    const float ay = y - fy;
    const int x0 = wrapIndex(static_cast<int>(fx), width_);
    const int x1 = wrapIndex(static_cast<int>(fx) + 1, width_);
    const int y0 = std::clamp(static_cast<int>(fy), 0, height_ - 1);
    const int y1 = std::clamp(static_cast<int>(fy) + 1, 0, height_ - 1);
    const Rgb top = (1 - ax) * texel(x0, y0) + ax * texel(x1, y0);
    const Rgb bottom = (1 - ax) * texel(x0, y1) + ax * texel(x1, y1);
    return (1 - ay) * top + ay * bottom;
}

Result<EnvironmentMap> EnvironmentMap::load(const std::filesystem::path& path) {
    Result<detail::LinearImage> image = detail::readLinearImage(path);
    if (!image)
        return image.status().withContext("loading environment map");
    return EnvironmentMap(Texture(image->width, image->height, std::move(image->texels)));
}

Rgb EnvironmentMap::radiance(const Eigen::Vector3f& d) const {
    if (texture_.empty())
        return Rgb::Zero();
    const Eigen::Vector2f pixel = pixelOf(d);
    return texture_.sample({(pixel.x() + 0.5f) / static_cast<float>(texture_.width()),
                            (pixel.y() + 0.5f) / static_cast<float>(texture_.height())});
}

Eigen::Vector2f EnvironmentMap::pixelOf(const Eigen::Vector3f& d) const {
    const float length = d.norm();
    const float z = length > 0 ? std::clamp(d.z() / length, -1.0f, 1.0f) : 1.0f;
    const float u = 0.5f - std::atan2(d.y(), d.x()) / (2 * kPi);
    const float v = std::acos(z) / kPi;
    return {u * static_cast<float>(texture_.width()) - 0.5f,
            v * static_cast<float>(texture_.height()) - 0.5f};
}

Eigen::Vector3f EnvironmentMap::directionOf(const Eigen::Vector2f& pixel) const {
    const float u = (pixel.x() + 0.5f) / static_cast<float>(std::max(texture_.width(), 1));
    const float v = (pixel.y() + 0.5f) / static_cast<float>(std::max(texture_.height(), 1));
    const float phi = (0.5f - u) * 2 * kPi;
    const float theta = v * kPi;
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

void EnvironmentMap::mirrorUpperIntoLower() {
    if (texture_.empty())
        return;
    const int width = texture_.width();
    const int height = texture_.height();
    std::vector<Rgb> texels(static_cast<size_t>(width) * height);
    for (int y = 0; y < height; ++y) {
        // Row centres v = (y + 0.5) / height and 1 - v belong to rows y and height - 1 - y.
        const int source = std::min(y, height - 1 - y);
        for (int x = 0; x < width; ++x) {
            texels[static_cast<size_t>(y) * width + x] = texture_.texel(x, source);
        }
    }
    texture_ = Texture(width, height, std::move(texels));
}

}  // namespace mixray::render
