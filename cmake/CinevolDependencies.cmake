# Finds the Debian-packaged libraries cinevol uses (scripts/install-deps.sh
# installs them).
find_package(Threads REQUIRED)
find_package(Protobuf REQUIRED)
find_package(spdlog REQUIRED)
find_package(CLI11 CONFIG REQUIRED)
find_package(PNG REQUIRED)
find_package(JPEG REQUIRED)
find_package(ZLIB REQUIRED)
find_package(OpenEXR CONFIG REQUIRED)
find_package(GTest REQUIRED)
find_package(gRPC CONFIG REQUIRED)
find_package(CURL REQUIRED)  # server/pacs: DICOMweb over HTTP and HTTPS
find_package(prometheus-cpp CONFIG REQUIRED)  # the server's /metrics (Exposer: prometheus-cpp::pull)

# DCMTK (Debian's libdcmtk-dev): dcmdata reads DICOM SEG inside the reader cage;
# the tests write SEGs with dcmseg.
find_package(DCMTK CONFIG REQUIRED)
# ITK pulls in many modules; ask only for the image I/O we use. Debian's GDCM
# config warns about command-line tools it does not ship: harmless.
find_package(ITK REQUIRED COMPONENTS
  ITKCommon ITKGDCM ITKIOImageBase ITKIONIFTI ITKIONRRD ITKIOMeta ITKIOVTK ITKIOGDCM)
