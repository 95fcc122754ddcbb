// The server's services as the page calls them: gRPC-web to the gateway that
// served the page, the token in each call's `authorization` header.
import { createClient, type Client, type Interceptor } from "@connectrpc/connect";
import { createGrpcWebTransport } from "@connectrpc/connect-web";
import { PacsService, ServerService, SessionService, VolumeService } from "../gen/cinevol/v1/service_pb.js";

export interface Api {
  sessions: Client<typeof SessionService>;
  volumes: Client<typeof VolumeService>;
  server: Client<typeof ServerService>;
  pacs: Client<typeof PacsService>;
}

export function connect(token: string, baseUrl: string): Api {
  const withToken: Interceptor = (next) => (request) => {
    request.header.set("authorization", `Bearer ${token}`);
    return next(request);
  };
  const transport = createGrpcWebTransport({ baseUrl, useBinaryFormat: true, interceptors: [withToken] });
  return {
    sessions: createClient(SessionService, transport),
    volumes: createClient(VolumeService, transport),
    server: createClient(ServerService, transport),
    pacs: createClient(PacsService, transport),
  };
}
