// The gRPC services (volumes, sessions, PACS, status): thin shells that authenticate, hand each request to the
// ServiceCore (slow work to its pools) and answer with the status its
// errors map to. Callback API: no reaction blocks.
#pragma once

#include <functional>
#include <string>

#include "cinevol/v1/service.grpc.pb.h"
#include "service/service_core.h"

namespace cinevol::service {

class VolumeServiceImpl final : public v1::VolumeService::CallbackService {
 public:
  explicit VolumeServiceImpl(ServiceCore* core) : core_(core) {}

  grpc::ServerUnaryReactor* ListVolumes(grpc::CallbackServerContext* context, const v1::ListVolumesRequest* request,
                                        v1::ListVolumesResponse* response) override;
  grpc::ServerUnaryReactor* LoadVolume(grpc::CallbackServerContext* context, const v1::LoadVolumeRequest* request,
                                       v1::VolumeInfo* response) override;
  grpc::ServerUnaryReactor* LoadLabels(grpc::CallbackServerContext* context, const v1::LoadLabelsRequest* request,
                                       v1::VolumeInfo* response) override;
  grpc::ServerReadReactor<v1::UploadVolumeChunk>* UploadVolume(grpc::CallbackServerContext* context,
                                                               v1::VolumeInfo* response) override;
  grpc::ServerUnaryReactor* DescribeVolume(grpc::CallbackServerContext* context,
                                           const v1::DescribeVolumeRequest* request,
                                           v1::VolumeInfo* response) override;
  grpc::ServerUnaryReactor* UnloadVolume(grpc::CallbackServerContext* context, const v1::UnloadVolumeRequest* request,
                                         v1::UnloadVolumeResponse* response) override;

 private:
  // Checks `path` against the data roots at once, then runs `load` on the
  // loader pool holding one of the caller's load slots (cancelled when the
  // caller goes away), and answers with it.
  grpc::ServerUnaryReactor* LoadFromDisk(grpc::CallbackServerContext* context, const std::string& path,
                                         std::function<void(const Principal&, LoadSlot&)> load);

  ServiceCore* core_;
};

class SessionServiceImpl final : public v1::SessionService::CallbackService {
 public:
  explicit SessionServiceImpl(ServiceCore* core) : core_(core) {}

  grpc::ServerUnaryReactor* CreateSession(grpc::CallbackServerContext* context,
                                          const v1::CreateSessionRequest* request,
                                          v1::CreateSessionResponse* response) override;
  grpc::ServerBidiReactor<v1::ClientMessage, v1::ServerMessage>* StreamSession(
      grpc::CallbackServerContext* context) override;
  grpc::ServerUnaryReactor* Snapshot(grpc::CallbackServerContext* context, const v1::SnapshotRequest* request,
                                     v1::SnapshotResponse* response) override;
  grpc::ServerWriteReactor<v1::SnapshotUpdate>* StreamSnapshot(grpc::CallbackServerContext* context,
                                                               const v1::SnapshotRequest* request) override;
  grpc::ServerWriteReactor<v1::MovieUpdate>* RenderMovie(grpc::CallbackServerContext* context,
                                                        const v1::MovieRequest* request) override;
  grpc::ServerUnaryReactor* CloseSession(grpc::CallbackServerContext* context, const v1::CloseSessionRequest* request,
                                         v1::CloseSessionResponse* response) override;
  grpc::ServerWriteReactor<v1::ServerMessage>* WatchSession(grpc::CallbackServerContext* context,
                                                             const v1::WatchSessionRequest* request) override;
  grpc::ServerUnaryReactor* SendEvents(grpc::CallbackServerContext* context, const v1::SendEventsRequest* request,
                                       v1::SendEventsResponse* response) override;
  grpc::ServerUnaryReactor* ShareSession(grpc::CallbackServerContext* context, const v1::ShareSessionRequest* request,
                                         v1::Grant* response) override;
  grpc::ServerUnaryReactor* ListShares(grpc::CallbackServerContext* context, const v1::ListSharesRequest* request,
                                       v1::ListSharesResponse* response) override;
  grpc::ServerUnaryReactor* RevokeShare(grpc::CallbackServerContext* context, const v1::RevokeShareRequest* request,
                                        v1::RevokeShareResponse* response) override;
  grpc::ServerUnaryReactor* HandOver(grpc::CallbackServerContext* context, const v1::HandOverRequest* request,
                                     v1::HandOverResponse* response) override;
  grpc::ServerUnaryReactor* RenderSlice(grpc::CallbackServerContext* context, const v1::SliceRequest* request,
                                        v1::SliceImage* response) override;
  grpc::ServerUnaryReactor* Pick(grpc::CallbackServerContext* context, const v1::PickRequest* request,
                                 v1::PickResult* response) override;

 private:
  ServiceCore* core_;
};

class PacsServiceImpl final : public v1::PacsService::CallbackService {
 public:
  explicit PacsServiceImpl(ServiceCore* core) : core_(core) {}

  grpc::ServerUnaryReactor* ListPacs(grpc::CallbackServerContext* context, const v1::ListPacsRequest* request,
                                     v1::ListPacsResponse* response) override;
  grpc::ServerUnaryReactor* SearchStudies(grpc::CallbackServerContext* context,
                                          const v1::SearchStudiesRequest* request,
                                          v1::SearchStudiesResponse* response) override;
  grpc::ServerUnaryReactor* SearchSeries(grpc::CallbackServerContext* context, const v1::SearchSeriesRequest* request,
                                         v1::SearchSeriesResponse* response) override;
  grpc::ServerWriteReactor<v1::LoadSeriesUpdate>* LoadSeries(grpc::CallbackServerContext* context,
                                                             const v1::LoadSeriesRequest* request) override;
  grpc::ServerUnaryReactor* StoreMeasurements(grpc::CallbackServerContext* context,
                                              const v1::StoreMeasurementsRequest* request,
                                              v1::StoredObject* response) override;
  grpc::ServerUnaryReactor* LoadMeasurements(grpc::CallbackServerContext* context,
                                             const v1::LoadMeasurementsRequest* request,
                                             v1::LoadMeasurementsResponse* response) override;
  grpc::ServerUnaryReactor* LoadPresentation(grpc::CallbackServerContext* context,
                                             const v1::LoadPresentationRequest* request,
                                             v1::LoadPresentationResponse* response) override;
  grpc::ServerUnaryReactor* RenderFrame(grpc::CallbackServerContext* context, const v1::RenderFrameRequest* request,
                                        v1::SliceImage* response) override;

 private:
  ServiceCore* core_;
};

class ServerServiceImpl final : public v1::ServerService::CallbackService {
 public:
  explicit ServerServiceImpl(ServiceCore* core) : core_(core) {}

  grpc::ServerUnaryReactor* GetStatus(grpc::CallbackServerContext* context, const v1::GetStatusRequest* request,
                                      v1::ServerStatus* response) override;

 private:
  ServiceCore* core_;
};

}  // namespace cinevol::service
