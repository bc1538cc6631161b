"""Getting animations out: GLB, USD, PC2 and OBJ writers, previews and videos."""
