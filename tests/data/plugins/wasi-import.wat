;; A component that imports a WASI interface (as a wasm32-wasip2 build does): the host must
;; refuse it before running anything.
(component
  (import "wasi:filesystem/types@0.2.0" (instance))
)
