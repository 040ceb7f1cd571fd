#include "mixray/dds/ros_calibration.h"

#include "mixray/dds/dds_publisher.h"

namespace mixray::dds {

Result<RosCalibration> rosCalibrationOf(const RigDescription& rig,
                                        const std::vector<StreamInfo>& streams,
                                        const CalibrationLoader& load) {
    RosCalibration out;
    std::map<std::string, calibration::CalibrationFile> files;  // by the rig's path
    for (const StreamInfo& info : streams) {
        if (!rosImageEncoding(info.format.format))
            continue;
        const RigCalibrationFile* entry =
            rig.findCalibration(info.device, info.name.substr(info.name.find('/') + 1));
        if (!entry)
            continue;
        auto found = files.find(entry->path);
        if (found == files.end()) {
            auto read = load(*entry);
            if (!read)
                return read.status();
            for (const calibration::RosTransform& t : calibration::toRosTransforms(*read)) {
                bool known = false;
                for (const auto& existing : out.transforms)
                    known = known || existing.child == t.child;
                if (!known)
                    out.transforms.push_back(t);
            }
            found = files.emplace(entry->path, std::move(read).value()).first;
        }
        const calibration::CalibrationFile& file = found->second;
        const calibration::CalibratedCamera* camera = file.find(info.name);
        if (!camera && !entry->stream.empty() && file.cameras.size() == 1)
            camera = &file.cameras.front();
        if (!camera)
            continue;
        auto camera_info = calibration::toRosCameraInfo(*camera);
        if (!camera_info)
            return camera_info.status();
        out.camera_info[info.name] = std::move(camera_info).value();
    }
    return out;
}

}  // namespace mixray::dds
